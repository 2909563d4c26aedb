//! The group: its parameters as a serde struct with a self-description, and one SoA batch
//! holding the attraction of every dynamic particle of the objects it is applied to.

use nucleus_sdk::params::{self, ParamSpec};
use nucleus_sdk::prelude::*;
use serde::{Deserialize, Serialize};

use crate::constraint::{attraction_constraint, project_attraction, Attractor};

/// The parameters of the kind, as written in a scene.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AttractParams {
    /// The point the particles are pulled toward (m). Default the origin.
    pub center: [f64; 3],
    /// Particles closer to the centre than this are free (m, ≥ 0). Default 0: pulled to the
    /// point itself.
    pub radius: f64,
    /// Natural period of the pull (s, ≥ 0): a particle released away from the centre swings
    /// back and forth in this time, whatever its mass. 0 is a hard pull. Default 0.5 s.
    pub period: f64,
    /// Particles farther from the centre than this are not pulled (m, ≥ 0); 0 for no limit.
    /// When set, it must exceed `radius`. Default 0.
    pub max_distance: f64,
}

impl Default for AttractParams {
    fn default() -> Self {
        Self {
            center: [0.0; 3],
            radius: 0.0,
            period: 0.5,
            max_distance: 0.0,
        }
    }
}

impl AttractParams {
    /// The self-description of every parameter: name, doc, unit, default and valid range.
    pub fn specs() -> Vec<ParamSpec> {
        let d = Self::default();
        vec![
            ParamSpec::vec3("center", d.center)
                .doc("the point the particles are pulled toward")
                .unit("m"),
            ParamSpec::number("radius", d.radius)
                .doc("particles closer to the centre than this are free; 0 pulls them to the point")
                .unit("m")
                .range(0.0, f64::INFINITY),
            ParamSpec::number("period", d.period)
                .doc("natural period of the pull, the same for every mass; 0 is a hard pull")
                .unit("s")
                .range(0.0, f64::INFINITY),
            ParamSpec::number("max_distance", d.max_distance)
                .doc("particles farther than this from the centre are not pulled; 0 for no limit")
                .unit("m")
                .range(0.0, f64::INFINITY),
        ]
    }

    /// Checks the values: the ranges of [`specs`](Self::specs) (the host checks those before
    /// the factory runs, but in-process callers may not), and what a range cannot say —
    /// `max_distance`, when set, must exceed `radius`. An error names the parameter.
    pub fn validate(&self) -> Result<(), PluginError> {
        params::validate_against(self, &Self::specs())?;
        if self.max_distance > 0.0 && self.max_distance <= self.radius {
            return Err(PluginError::bad_parameter(
                "max_distance",
                format!(
                    "{} m must be 0 (no limit) or larger than radius = {} m",
                    self.max_distance, self.radius
                ),
            ));
        }
        Ok(())
    }

    /// The attractor these parameters describe.
    pub fn attractor(&self) -> Attractor {
        let reach = if self.max_distance > 0.0 {
            self.max_distance
        } else {
            f64::INFINITY
        };
        Attractor::new(
            DVec3::from_array(self.center),
            self.radius,
            reach,
            self.period,
        )
    }
}

/// Every attracted particle of one group, struct-of-arrays.
#[derive(Clone, Debug)]
pub struct AttractGroup {
    /// Global index of each attracted particle, increasing.
    ids: Vec<u32>,
    /// Multiplier of each particle accumulated over the passes of the current substep (N·s²).
    lambda: Vec<f64>,
    /// Centre, radius, reach and strength.
    attractor: Attractor,
}

impl AttractGroup {
    /// One constraint per dynamic particle of every target object (kinematic particles, with
    /// inverse mass 0, are never moved and are left out; an object listed twice counts once).
    ///
    /// Errors: a parameter out of range (naming it); a target index outside the scene, or an
    /// object whose particles lie outside the scene's (naming the object).
    pub fn new(params: &AttractParams, scene: &SceneView<'_>) -> Result<Self, PluginError> {
        params.validate()?;
        let inv_mass = scene.inv_mass.as_slice();
        // Each target once, checked against the scene; in object order, so that `ids` ascend.
        let mut targets = scene.unique_targets()?;
        targets.sort_unstable_by_key(|&(t, _)| t);
        let ids: Vec<u32> = targets
            .iter()
            .flat_map(|(_, o)| o.particles())
            .filter(|&i| inv_mass[i] > 0.0)
            .map(|i| i as u32)
            .collect();
        Ok(Self {
            lambda: vec![0.0; ids.len()],
            ids,
            attractor: params.attractor(),
        })
    }

    /// The attracted particles, as global indices.
    pub fn ids(&self) -> &[u32] {
        &self.ids
    }

    /// The attractor.
    pub fn attractor(&self) -> &Attractor {
        &self.attractor
    }

    /// The largest particle index of the group (`ids` ascend).
    fn max_index(&self) -> Option<u32> {
        self.ids.last().copied()
    }
}

impl ConstraintGroup for AttractGroup {
    fn stages(&self) -> Stages {
        Stages::BEGIN_SUBSTEP | Stages::PROJECT | Stages::REPORT
    }

    fn len(&self) -> usize {
        self.ids.len()
    }

    /// Resets every λ to 0: XPBD's λ is the total multiplier of the substep, and the
    /// positions just predicted carry none of it yet.
    fn begin_substep(&mut self, _ctx: &mut SolveContext<'_>) -> Result<(), PluginError> {
        self.lambda.fill(0.0);
        Ok(())
    }

    /// One pass over the particles in index order: deterministic, no allocation.
    fn project(&mut self, ctx: &mut SolveContext<'_>) -> Result<(), PluginError> {
        // The checks every group makes before using `h` and indexing the state.
        let h = ctx.substep_length()?;
        ctx.check_holds(self.max_index())?;
        let p = ctx.particles();
        let (x, w) = (p.x, p.inv_mass);
        let attractor = self.attractor;
        for (&i, lambda) in self.ids.iter().zip(&mut self.lambda) {
            let i = i as usize;
            if let Some(c) = project_attraction(x[i], w[i], &attractor, *lambda, h) {
                x[i] += c.dx;
                *lambda += c.delta_lambda;
            }
        }
        Ok(())
    }

    /// How far each particle within reach is outside the free ball, `max(C, 0)` (m), and the
    /// energy `Σ ½ C²/α` of the soft pulls (J).
    fn residual(&self, ctx: &SolveContext<'_>) -> Residual {
        let x = ctx.positions();
        let w = ctx.inv_mass.as_slice();
        let a = &self.attractor;
        let mut out = Residual::default();
        let mut sum_sq = 0.0;
        for &i in &self.ids {
            let i = i as usize;
            let (Some(&xi), Some(&wi)) = (x.get(i), w.get(i)) else {
                continue;
            };
            let Some((c, _)) = attraction_constraint(xi, a.center, a.radius) else {
                out.count += 1;
                continue;
            };
            if c + a.radius > a.reach {
                continue;
            }
            let violation = c.max(0.0);
            out.count += 1;
            out.max = out.max.max(violation);
            sum_sq += violation * violation;
            let alpha = a.compliance(wi);
            if alpha > 0.0 {
                out.energy += 0.5 * violation * violation / alpha;
            }
        }
        if out.count > 0 {
            out.rms = (sum_sq / out.count as f64).sqrt();
        }
        out
    }

    /// `mean_distance`: the mean distance of the group's particles from the centre (m).
    fn report(&self, ctx: &SolveContext<'_>, out: &mut Vec<(String, f64)>) {
        let x = ctx.positions();
        let sum: f64 = self
            .ids
            .iter()
            .filter_map(|&i| x.get(i as usize))
            .map(|&xi| (xi - self.attractor.center).length())
            .sum();
        let mean = if self.ids.is_empty() {
            0.0
        } else {
            sum / self.ids.len() as f64
        };
        out.push(("mean_distance".to_string(), mean));
    }
}

/// The factory of the kind.
pub(crate) fn build(
    params_json: &str,
    scene: &SceneView<'_>,
) -> Result<Box<dyn ConstraintGroup>, PluginError> {
    let params: AttractParams = params::parse(params_json)?;
    Ok(Box::new(AttractGroup::new(&params, scene)?))
}
