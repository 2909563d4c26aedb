//! How an analytic collider moves: static, at a constant linear and angular velocity about a
//! pivot, or along keyframes; its [`Pose`] at any time maps its rest frame to the world.

use glam::{DQuat, DVec3, EulerRot};

/// One keyframe of a collider's rigid motion.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Key {
    /// Time (s).
    pub time: f64,
    /// Translation (m).
    pub translate: DVec3,
    /// Rotation about the pivot as an axis-angle vector (rad), as in the core's pin motion
    /// keys.
    pub rotate: DVec3,
}

/// How a collider moves.
#[derive(Clone, Debug, PartialEq)]
pub enum Motion {
    /// It does not.
    Static,
    /// `x(t) = pivot + exp(ω t)(q − pivot) + v t`.
    Constant {
        /// Centre of rotation (m).
        pivot: DVec3,
        /// Linear velocity (m/s).
        velocity: DVec3,
        /// Angular velocity (rad/s).
        angular_velocity: DVec3,
    },
    /// Keys, interpolated like the core's pinned-vertex keys: translation linearly,
    /// rotation by slerp, held before the first and after the last key.
    Keys {
        /// Centre of rotation (m).
        pivot: DVec3,
        /// Keys, by increasing time.
        keys: Vec<Key>,
    },
}

/// A rigid pose: `world = rot · q + trans`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pose {
    /// Rotation.
    pub rot: DQuat,
    /// Translation (m).
    pub trans: DVec3,
}

impl Pose {
    /// The identity.
    pub const IDENTITY: Self = Self {
        rot: DQuat::IDENTITY,
        trans: DVec3::ZERO,
    };
    /// Rest frame to world.
    #[inline]
    pub fn apply(&self, q: DVec3) -> DVec3 {
        self.rot * q + self.trans
    }
    /// World to rest frame.
    #[inline]
    pub fn inverse_apply(&self, x: DVec3) -> DVec3 {
        self.rot.inverse() * (x - self.trans)
    }
    /// A direction from the rest frame to the world.
    #[inline]
    pub fn rotate(&self, n: DVec3) -> DVec3 {
        self.rot * n
    }
    /// The rotation `R` about `pivot` followed by the translation `t`.
    pub fn about(pivot: DVec3, rot: DQuat, t: DVec3) -> Self {
        Self {
            rot,
            trans: pivot - rot * pivot + t,
        }
    }
}

/// Maya's `xyz` rotation order (rotate about X first, then Y, then Z) from degrees.
pub fn euler_xyz_degrees(deg: DVec3) -> DQuat {
    let r = deg * (std::f64::consts::PI / 180.0);
    DQuat::from_euler(EulerRot::ZYX, r.z, r.y, r.x)
}

impl Motion {
    /// The pose at time `t` (s).
    pub fn pose(&self, t: f64) -> Pose {
        match self {
            Motion::Static => Pose::IDENTITY,
            Motion::Constant {
                pivot,
                velocity,
                angular_velocity,
            } => Pose::about(
                *pivot,
                DQuat::from_scaled_axis(*angular_velocity * t),
                *velocity * t,
            ),
            Motion::Keys { pivot, keys } => {
                let rot = |k: &Key| DQuat::from_scaled_axis(k.rotate);
                let (rotation, translate) = match keys.iter().position(|k| k.time > t) {
                    Some(0) => (rot(&keys[0]), keys[0].translate),
                    None => {
                        let k = &keys[keys.len() - 1];
                        (rot(k), k.translate)
                    }
                    Some(i) => {
                        let (a, b) = (&keys[i - 1], &keys[i]);
                        let s = ((t - a.time) / (b.time - a.time)).clamp(0.0, 1.0);
                        (rot(a).slerp(rot(b), s), a.translate.lerp(b.translate, s))
                    }
                };
                Pose::about(*pivot, rotation, translate)
            }
        }
    }

    /// Whether the collider never moves.
    pub fn is_static(&self) -> bool {
        matches!(self, Motion::Static)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn poses_follow_velocity_and_keys() {
        let m = Motion::Constant {
            pivot: DVec3::new(1.0, 0.0, 0.0),
            velocity: DVec3::new(0.0, 2.0, 0.0),
            angular_velocity: DVec3::new(0.0, 0.0, std::f64::consts::FRAC_PI_2),
        };
        let p = m.pose(1.0);
        // The pivot only translates; a point 1 m from it turns by 90° about z.
        assert!((p.apply(DVec3::new(1.0, 0.0, 0.0)) - DVec3::new(1.0, 2.0, 0.0)).length() < 1e-12);
        assert!((p.apply(DVec3::new(2.0, 0.0, 0.0)) - DVec3::new(1.0, 3.0, 0.0)).length() < 1e-12);
        let q = DVec3::new(0.3, -0.2, 0.7);
        assert!((p.inverse_apply(p.apply(q)) - q).length() < 1e-12);

        let keys = Motion::Keys {
            pivot: DVec3::ZERO,
            keys: vec![
                Key {
                    time: 0.0,
                    translate: DVec3::ZERO,
                    rotate: DVec3::ZERO,
                },
                Key {
                    time: 2.0,
                    translate: DVec3::new(4.0, 0.0, 0.0),
                    rotate: DVec3::new(0.0, std::f64::consts::FRAC_PI_2, 0.0),
                },
            ],
        };
        let mid = keys.pose(1.0);
        assert!((mid.trans - DVec3::new(2.0, 0.0, 0.0)).length() < 1e-12);
        let x = mid.apply(DVec3::Z);
        let s = std::f64::consts::FRAC_1_SQRT_2;
        assert!((x - DVec3::new(2.0 + s, 0.0, s)).length() < 1e-12, "{x}");
        assert_eq!(keys.pose(-1.0), keys.pose(0.0));
        assert_eq!(keys.pose(5.0), keys.pose(2.0));
    }
}
