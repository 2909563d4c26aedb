//! The `air` group: every surface triangle, curve edge and isolated point of the objects the
//! group is applied to, as SoA batches over the group's own compact list of particles, and
//! the force stage that applies the air to them.

use nucleus_sdk::params::{self, ParamSpec};
use nucleus_sdk::prelude::*;
use serde::{Deserialize, Serialize};

use crate::aero::{
    apply_impulse, edge_force, point_force, triangle_force, Coefficients, ElementForce,
};
use crate::wind::Wind;

/// Largest valid `seed`: integers up to 2⁵³ − 1 survive the trip through a scene's numbers.
pub const MAX_SEED: u64 = (1 << 53) - 1;

/// Smallest valid `noise_scale` (m).
pub const MIN_NOISE_SCALE: f64 = 1e-6;

/// The parameters of the `air` kind, as written in a scene.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AirParams {
    /// Drag coefficient `C_d` (dimensionless, ≥ 0). Default 0.05 (Maya's nCloth Drag).
    pub drag: f64,
    /// Lift coefficient `C_l` (dimensionless, ≥ 0). Default 0 (Maya's nCloth Lift).
    pub lift: f64,
    /// Skin drag along a surface or curve, as a fraction of `drag` (dimensionless, ≥ 0):
    /// `C_t = tangential_drag · C_d`. Default 0.1 (Maya's nCloth Tangential Drag).
    pub tangential_drag: f64,
    /// Air density ρ (kg/m³, ≥ 0). Default 1.2 (sea level, 20 °C).
    pub air_density: f64,
    /// Wind speed `U` (m/s, ≥ 0). Default 0: still air.
    pub wind_speed: f64,
    /// Direction the wind blows towards; normalised, must not be zero. Default `[1, 0, 0]`.
    pub wind_direction: [f64; 3],
    /// Turbulence amplitude `a` (m/s, ≥ 0): each wind component varies within `±a`.
    /// Default 0: steady wind.
    pub noise: f64,
    /// How fast the turbulence changes (Hz, ≥ 0); 0 freezes the pattern, which still travels
    /// with the wind. Default 1.
    pub noise_frequency: f64,
    /// Size of the gusts (m, ≥ 1e-6). Default 1.
    pub noise_scale: f64,
    /// Seed of the turbulence (integer in [0, 2⁵³ − 1]). Default 0.
    pub seed: u64,
    /// Thickness of curves (ropes, hair) facing the air (m, ≥ 0). Default 0.01.
    pub curve_width: f64,
    /// Radius of isolated particles facing the air (m, ≥ 0). Default 0.01.
    pub particle_radius: f64,
}

impl Default for AirParams {
    fn default() -> Self {
        Self {
            drag: 0.05,
            lift: 0.0,
            tangential_drag: 0.1,
            air_density: 1.2,
            wind_speed: 0.0,
            wind_direction: [1.0, 0.0, 0.0],
            noise: 0.0,
            noise_frequency: 1.0,
            noise_scale: 1.0,
            seed: 0,
            curve_width: 0.01,
            particle_radius: 0.01,
        }
    }
}

impl AirParams {
    /// The self-description of every parameter: name, doc, unit, default and valid range.
    pub fn specs() -> Vec<ParamSpec> {
        let d = Self::default();
        let inf = f64::INFINITY;
        vec![
            ParamSpec::number("drag", d.drag)
                .doc("drag coefficient C_d: F = ½ ρ C_d A |v_n| |v_rel| against the relative velocity (flat plate ≈ 1.2; Maya's default 0.05)")
                .range(0.0, inf),
            ParamSpec::number("lift", d.lift)
                .doc("lift coefficient C_l: F = ½ ρ C_l A |v_n| |v_t| perpendicular to the relative velocity (triangles only; a flag needs lift to flap)")
                .range(0.0, inf),
            ParamSpec::number("tangential_drag", d.tangential_drag)
                .doc("skin drag along the surface (and along curves) as a fraction of drag, as Maya's Tangential Drag")
                .range(0.0, inf),
            ParamSpec::number("air_density", d.air_density)
                .doc("air density ρ (sea level 1.2; Maya's nucleus uses 1.0)")
                .unit("kg/m³")
                .range(0.0, inf),
            ParamSpec::number("wind_speed", d.wind_speed)
                .doc("speed of the mean wind")
                .unit("m/s")
                .range(0.0, inf),
            ParamSpec::vec3("wind_direction", d.wind_direction)
                .doc("direction the wind blows towards (normalised; must not be zero)"),
            ParamSpec::number("noise", d.noise)
                .doc("turbulence amplitude: each wind component varies smoothly within ± this; 0 is a steady wind")
                .unit("m/s")
                .range(0.0, inf),
            ParamSpec::number("noise_frequency", d.noise_frequency)
                .doc("how fast the turbulence changes; 0 freezes the pattern (it still travels with the wind)")
                .unit("Hz")
                .range(0.0, inf),
            ParamSpec::number("noise_scale", d.noise_scale)
                .doc("size of the gusts")
                .unit("m")
                .range(MIN_NOISE_SCALE, inf),
            ParamSpec::integer("seed", d.seed as i64)
                .doc("seed of the turbulence: the same seed gives bit-identical runs")
                .range(0.0, MAX_SEED as f64),
            ParamSpec::number("curve_width", d.curve_width)
                .doc("thickness of curves facing the air: an edge of length L has area L × width")
                .unit("m")
                .range(0.0, inf),
            ParamSpec::number("particle_radius", d.particle_radius)
                .doc("radius of isolated particles facing the air: area π r²")
                .unit("m")
                .range(0.0, inf),
        ]
    }

    /// Checks the values against [`specs`](Self::specs) and the wind direction against
    /// zero; an error names the parameter.
    pub fn validate(&self) -> Result<(), PluginError> {
        params::validate_against(self, &Self::specs())?;
        let d = DVec3::from_array(self.wind_direction);
        let len = d.length();
        if !(len.is_finite() && len > 1e-12) {
            return Err(PluginError::bad_parameter(
                "wind_direction",
                format!(
                    "{:?} has no direction: give a non-zero vector",
                    self.wind_direction
                ),
            ));
        }
        Ok(())
    }

    /// The coefficients these parameters describe (premultiplied by ½ρ).
    pub fn coefficients(&self) -> Coefficients {
        Coefficients::new(self.air_density, self.drag, self.lift, self.tangential_drag)
    }

    /// The wind these parameters describe (call after [`validate`](Self::validate)).
    pub fn wind(&self) -> Wind {
        Wind {
            velocity: DVec3::from_array(self.wind_direction).normalize_or_zero() * self.wind_speed,
            noise: self.noise,
            frequency: self.noise_frequency,
            scale: self.noise_scale,
            seed: self.seed,
        }
    }
}

/// The sum over the group of each term of the air's force (N), at the last force stage.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Totals {
    /// Sum of the drag forces (N).
    pub drag: DVec3,
    /// Sum of the lift forces (N).
    pub lift: DVec3,
    /// Sum of the tangential drag forces (N).
    pub tangential: DVec3,
}

impl Totals {
    /// The total aerodynamic force (N).
    pub fn total(&self) -> DVec3 {
        self.drag + self.lift + self.tangential
    }

    fn add(&mut self, f: &ElementForce) {
        self.drag += f.drag;
        self.lift += f.lift;
        self.tangential += f.tangential;
    }
}

/// All the elements of one `air` group, struct-of-arrays, over a compact local numbering of
/// the particles they touch.
#[derive(Clone, Debug)]
pub struct AirGroup {
    /// Global index of each local particle, increasing.
    particles: Vec<u32>,
    /// Surface triangles (local indices), in their winding.
    triangles: Vec<[u32; 3]>,
    /// Curve edges (local indices).
    edges: Vec<[u32; 2]>,
    /// Isolated points (local indices).
    points: Vec<u32>,
    coefficients: Coefficients,
    wind: Wind,
    curve_width: f64,
    particle_radius: f64,
    /// Scratch, per local particle: the wind at it (m/s); constant for a uniform wind.
    wind_at: Vec<DVec3>,
    /// Scratch, per local particle: the accumulated force (N) and rate β (N·s/m).
    force: Vec<DVec3>,
    rate: Vec<f64>,
    /// The force of the last force stage, by term.
    totals: Totals,
}

impl AirGroup {
    /// Every surface triangle (in no tet, or on a solid's boundary), curve edge (in no
    /// triangle) and isolated point of the target objects. An object listed twice among the
    /// targets is used once. Elements whose particles are all kinematic are kept: the air
    /// still acts on a held object, and its force is reported, though nothing moves.
    ///
    /// Errors: a parameter out of range or a zero wind direction (naming it); a simplex
    /// outside its object's particle range, or per-simplex counts of the wrong length
    /// (naming the object); a target index outside the scene.
    pub fn new(params: &AirParams, scene: &SceneView<'_>) -> Result<Self, PluginError> {
        params.validate()?;
        let particle_count = scene.rest.len().min(scene.inv_mass.len());

        let mut global_triangles = Vec::new();
        let mut global_edges = Vec::new();
        let mut global_points = Vec::new();
        for (_, object) in scene.unique_targets()? {
            let name = object.name.as_str();
            let range = object.particles();
            let check = |ids: &[u32], what: &str| -> Result<(), PluginError> {
                match ids
                    .iter()
                    .find(|&&i| !range.contains(&(i as usize)) || i as usize >= particle_count)
                {
                    Some(i) => Err(PluginError::bad_object(
                        name,
                        format!(
                            "{what} {ids:?} refers to particle {i}, outside the object's particles \
                             {}..{} (the scene has {particle_count})",
                            range.start, range.end
                        ),
                    )),
                    None => Ok(()),
                }
            };
            let triangles = object.triangles.as_slice();
            let tet_counts = object.triangle_tet_count.as_slice();
            if !tet_counts.is_empty() && tet_counts.len() != triangles.len() {
                return Err(PluginError::bad_object(
                    name,
                    format!(
                        "{} tet counts for {} triangles",
                        tet_counts.len(),
                        triangles.len()
                    ),
                ));
            }
            for (k, tri) in triangles.iter().enumerate() {
                // Triangles shared by two tets are inside a solid: the air never sees them.
                if tet_counts.get(k).is_some_and(|&c| c >= 2) {
                    continue;
                }
                check(tri, "triangle")?;
                global_triangles.push(*tri);
            }
            let edges = object.edges.as_slice();
            let tri_counts = object.edge_triangle_count.as_slice();
            if tri_counts.len() != edges.len() && !(tri_counts.is_empty() && triangles.is_empty()) {
                return Err(PluginError::bad_object(
                    name,
                    format!(
                        "{} triangle counts for {} edges",
                        tri_counts.len(),
                        edges.len()
                    ),
                ));
            }
            for (k, edge) in edges.iter().enumerate() {
                // Edges of triangles are covered by the triangles.
                if tri_counts.get(k).is_some_and(|&c| c > 0) {
                    continue;
                }
                check(edge, "edge")?;
                global_edges.push(*edge);
            }
            for &p in object.points.as_slice() {
                check(&[p], "point")?;
                global_points.push(p);
            }
        }

        // The compact numbering: the group's particles in increasing global order.
        let mut particles: Vec<u32> = global_triangles
            .iter()
            .flatten()
            .chain(global_edges.iter().flatten())
            .chain(&global_points)
            .copied()
            .collect();
        particles.sort_unstable();
        particles.dedup();
        let local = |g: u32| particles.binary_search(&g).unwrap_or(0) as u32;
        let triangles = global_triangles
            .iter()
            .map(|t| t.map(&local))
            .collect::<Vec<_>>();
        let edges = global_edges
            .iter()
            .map(|e| e.map(&local))
            .collect::<Vec<_>>();
        let points = global_points.iter().map(|&p| local(p)).collect::<Vec<_>>();

        let wind = params.wind();
        let n = particles.len();
        Ok(Self {
            particles,
            triangles,
            edges,
            points,
            coefficients: params.coefficients(),
            wind,
            curve_width: params.curve_width,
            particle_radius: params.particle_radius,
            wind_at: vec![wind.velocity; n],
            force: vec![DVec3::ZERO; n],
            rate: vec![0.0; n],
            totals: Totals::default(),
        })
    }

    /// The surface triangles, as global particle indices.
    pub fn triangles(&self) -> impl Iterator<Item = [u32; 3]> + '_ {
        self.triangles
            .iter()
            .map(|t| t.map(|l| self.particles[l as usize]))
    }

    /// The curve edges, as global particle indices.
    pub fn edges(&self) -> impl Iterator<Item = [u32; 2]> + '_ {
        self.edges
            .iter()
            .map(|e| e.map(|l| self.particles[l as usize]))
    }

    /// The isolated points, as global particle indices.
    pub fn points(&self) -> impl Iterator<Item = u32> + '_ {
        self.points.iter().map(|&l| self.particles[l as usize])
    }

    /// The wind of the group.
    pub fn wind(&self) -> &Wind {
        &self.wind
    }

    /// The force of the last force stage, by term (zero before the first).
    pub fn totals(&self) -> &Totals {
        &self.totals
    }

    /// The largest particle index of the group (its particles are sorted).
    fn max_index(&self) -> Option<u32> {
        self.particles.last().copied()
    }

    /// The force stage: the air's force on every element from the positions and velocities
    /// at the start of the substep, split equally over the element's vertices, applied as
    /// `Δv = h w F / (1 + h w β)` to every dynamic particle. Allocates nothing.
    fn apply(&mut self, ctx: &mut SolveContext<'_>) -> Result<(), PluginError> {
        let h = ctx.substep_length()?;
        ctx.check_holds(self.max_index())?;
        let time = ctx.time;
        let p = ctx.particles();
        let flags = p.flags;
        let (x, v, inv_mass) = (&*p.x, &mut *p.v, p.inv_mass);
        let ids = &self.particles;
        if !self.wind.is_uniform() {
            for (w, &g) in self.wind_at.iter_mut().zip(ids) {
                *w = self.wind.at(x[g as usize], time);
            }
        }
        self.force.fill(DVec3::ZERO);
        self.rate.fill(0.0);
        let mut totals = Totals::default();
        let (wind_at, force, rate) = (&self.wind_at, &mut self.force, &mut self.rate);
        let k = &self.coefficients;

        for tri in &self.triangles {
            let [a, b, c] = tri.map(|l| l as usize);
            let [ga, gb, gc] = [ids[a], ids[b], ids[c]].map(|g| g as usize);
            let v_rel = (v[ga] + v[gb] + v[gc] - wind_at[a] - wind_at[b] - wind_at[c]) / 3.0;
            let f = triangle_force([x[ga], x[gb], x[gc]], v_rel, k);
            totals.add(&f);
            let (share, r) = (f.total() / 3.0, f.rate / 3.0);
            for l in [a, b, c] {
                force[l] += share;
                rate[l] += r;
            }
        }
        for edge in &self.edges {
            let [a, b] = edge.map(|l| l as usize);
            let [ga, gb] = [ids[a], ids[b]].map(|g| g as usize);
            let v_rel = 0.5 * (v[ga] + v[gb] - wind_at[a] - wind_at[b]);
            let f = edge_force([x[ga], x[gb]], v_rel, self.curve_width, k);
            totals.add(&f);
            let (share, r) = (0.5 * f.total(), 0.5 * f.rate);
            for l in [a, b] {
                force[l] += share;
                rate[l] += r;
            }
        }
        for &l in &self.points {
            let l = l as usize;
            let g = ids[l] as usize;
            let f = point_force(v[g] - wind_at[l], self.particle_radius, k);
            totals.add(&f);
            force[l] += f.total();
            rate[l] += f.rate;
        }

        for (l, &g) in ids.iter().enumerate() {
            let g = g as usize;
            let w = inv_mass[g];
            let kinematic = flags.get(g).is_some_and(|&f| f & FLAG_KINEMATIC != 0);
            if w > 0.0 && !kinematic {
                let dv = apply_impulse(w, h, force[l], rate[l]);
                // A particle with a finite but absurd inverse mass could overflow: skip it.
                if dv.is_finite() {
                    v[g] += dv;
                }
            }
        }
        self.totals = totals;
        Ok(())
    }

    /// The relative speed `|v_rel|` (m/s) of every element, at the context's state.
    fn relative_speeds<'s>(&'s self, ctx: &'s SolveContext<'_>) -> impl Iterator<Item = f64> + 's {
        let (x, v) = (ctx.positions(), ctx.velocities());
        let ids = &self.particles;
        let ok = ctx.check_holds(self.max_index()).is_ok();
        let wind = |g: usize| self.wind.at(x[g], ctx.time);
        let rel = move |g: usize| v[g] - wind(g);
        let tris = self.triangles.iter().filter(move |_| ok).map(move |t| {
            let [a, b, c] = t.map(|l| ids[l as usize] as usize);
            ((rel(a) + rel(b) + rel(c)) / 3.0).length()
        });
        let edges = self.edges.iter().filter(move |_| ok).map(move |e| {
            let [a, b] = e.map(|l| ids[l as usize] as usize);
            (0.5 * (rel(a) + rel(b))).length()
        });
        let points = self
            .points
            .iter()
            .filter(move |_| ok)
            .map(move |&l| rel(ids[l as usize] as usize).length());
        tris.chain(edges).chain(points)
    }
}

impl ConstraintGroup for AirGroup {
    fn stages(&self) -> Stages {
        Stages::FORCE | Stages::REPORT
    }

    fn len(&self) -> usize {
        self.triangles.len() + self.edges.len() + self.points.len()
    }

    fn force(&mut self, ctx: &mut SolveContext<'_>) -> Result<(), PluginError> {
        self.apply(ctx)
    }

    /// The air is a force, not a constraint: its "residual" is how fast the elements move
    /// through the air, `|v_rel|` (m/s) — the speed the drag works to remove.
    fn residual(&self, ctx: &SolveContext<'_>) -> Residual {
        let (mut count, mut max, mut sum_sq) = (0u64, 0.0f64, 0.0);
        for s in self.relative_speeds(ctx) {
            count += 1;
            max = max.max(s);
            sum_sq += s * s;
        }
        Residual {
            count,
            max,
            rms: if count > 0 {
                (sum_sq / count as f64).sqrt()
            } else {
                0.0
            },
            energy: 0.0,
        }
    }

    /// The air's force on the group at the last substep (N): its components and the size of
    /// each term's sum.
    fn report(&self, _ctx: &SolveContext<'_>, out: &mut Vec<(String, f64)>) {
        let t = &self.totals;
        let f = t.total();
        out.extend([
            ("force_x".to_string(), f.x),
            ("force_y".to_string(), f.y),
            ("force_z".to_string(), f.z),
            ("drag".to_string(), t.drag.length()),
            ("lift".to_string(), t.lift.length()),
            ("tangential".to_string(), t.tangential.length()),
        ]);
    }
}

/// The factory of the `air` kind.
pub fn build(
    params_json: &str,
    scene: &SceneView<'_>,
) -> Result<Box<dyn ConstraintGroup>, PluginError> {
    let params: AirParams = params::parse(params_json)?;
    Ok(Box::new(AirGroup::new(&params, scene)?))
}
