//! The `pressure` and `gas` groups: their parameters, the struct-of-arrays batch of chambers
//! they share, and the stages the core calls. All numerics live in [`crate::geometry`] and
//! [`crate::solve`]; this file only loops over chambers.

use glam::DVec3;
use nucleus_sdk::prelude::*;
use serde::{Deserialize, Serialize};

use crate::geometry::{Cubic, Measure, Surface};
use crate::solve;
use crate::topology;

/// The smallest volume a chamber is taken to have, as a fraction of `A^{3/2}` with `A` its
/// rest area (a sphere of area `A` holds `A^{3/2}/(6√π) ≈ 0.094 A^{3/2}`): a collapsed or
/// inverted chamber is treated as this small, so `p = n/V` stays finite.
pub const VOLUME_FLOOR: f64 = 1e-6;

/// Sea-level atmospheric pressure (Pa): the default `incompressibility`.
pub const ATMOSPHERE: f64 = 101_325.0;

// ---------------------------------------------------------------------------------------------
// Parameters
// ---------------------------------------------------------------------------------------------

/// The parameters of the `pressure` kind (Maya's manual pressure), as written in a scene.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PressureParams {
    /// Target volume of each closed chamber as a multiple of its rest volume
    /// (dimensionless, ≥ 0). Default 1: keep the rest volume.
    pub pressure_scale: f64,
    /// Relative volume change per pascal of pressure (1/Pa, ≥ 0), the inverse of the
    /// chamber's bulk modulus: the constraint's compliance is `α = compliance · V_rest`
    /// (m³/Pa). Default 0: a hard volume constraint.
    pub compliance: f64,
    /// Gauge pressure pushing along the surface normals (Pa). On an open chamber a force
    /// `p A n / 3` on each vertex of each triangle; on a closed one it moves the target by
    /// `α p` (no effect on a hard constraint). Default 0.
    pub pressure: f64,
}

impl Default for PressureParams {
    fn default() -> Self {
        Self {
            pressure_scale: 1.0,
            compliance: 0.0,
            pressure: 0.0,
        }
    }
}

impl PressureParams {
    /// The self-description of every parameter: name, doc, unit, default and valid range.
    pub fn specs() -> Vec<ParamSpec> {
        let d = Self::default();
        vec![
            ParamSpec::number("pressure_scale", d.pressure_scale)
                .doc("target volume of each closed mesh as a multiple of its rest volume (Maya's manual pressure)")
                .range(0.0, f64::INFINITY),
            ParamSpec::number("compliance", d.compliance)
                .doc("relative volume change per pascal (1 / bulk modulus) of closed meshes; 0 is a hard volume constraint")
                .unit("1/Pa")
                .range(0.0, f64::INFINITY),
            ParamSpec::number("pressure", d.pressure)
                .doc("gauge pressure along the normals: pushes open meshes (sails), inflates soft closed ones by compliance x pressure")
                .unit("Pa"),
        ]
    }

    /// Checks the values against [`specs`](Self::specs); an error names the parameter.
    pub fn validate(&self) -> Result<(), PluginError> {
        params::validate_against(self, &Self::specs())
    }
}

/// The parameters of the `gas` kind (Maya's volume tracking model), as written in a scene.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GasParams {
    /// Gauge pressure of the gas at the start (Pa, above ambient; > −incompressibility).
    /// Default 0: the chamber holds air at ambient pressure.
    pub start_pressure: f64,
    /// Gas pumped in per second, in the units of `n = p V` (Pa·m³/s; negative draws it out):
    /// 101.3 Pa·m³ is one litre of air at sea-level pressure. Default 0.
    pub pump_rate: f64,
    /// How airtight the openings are (0 to 1): the volume flow through openings of area `A`
    /// is `(1 − air_tightness) A Δp / ρc`. Default 1: no leak.
    pub air_tightness: f64,
    /// How stiffly pressure answers volume change: the isothermal bulk modulus of the gas at
    /// ambient pressure, `−V dp/dV` (Pa), which for an ideal gas is the ambient absolute
    /// pressure itself. Default 101325 Pa, air at sea level; lower is softer.
    pub incompressibility: f64,
}

impl Default for GasParams {
    fn default() -> Self {
        Self {
            start_pressure: 0.0,
            pump_rate: 0.0,
            air_tightness: 1.0,
            incompressibility: ATMOSPHERE,
        }
    }
}

impl GasParams {
    /// The self-description of every parameter: name, doc, unit, default and valid range.
    pub fn specs() -> Vec<ParamSpec> {
        let d = Self::default();
        vec![
            ParamSpec::number("start_pressure", d.start_pressure)
                .doc("gauge pressure of the gas at the start, above ambient (must exceed -incompressibility)")
                .unit("Pa"),
            ParamSpec::number("pump_rate", d.pump_rate)
                .doc("gas pumped in per second as p*V (101.3 Pa*m^3 is a litre of sea-level air); negative draws it out")
                .unit("Pa·m³/s"),
            ParamSpec::number("air_tightness", d.air_tightness)
                .doc("1 is airtight; below 1 the gas leaks through holes and open edges in proportion to the pressure difference")
                .range(0.0, 1.0),
            ParamSpec::number("incompressibility", d.incompressibility)
                .doc("bulk modulus of the gas at ambient pressure (= ambient absolute pressure for an ideal gas); lower is softer")
                .unit("Pa")
                .range(1e-6, f64::INFINITY),
        ]
    }

    /// Checks the values against [`specs`](Self::specs) and that the start pressure is above
    /// vacuum; an error names the parameter.
    pub fn validate(&self) -> Result<(), PluginError> {
        params::validate_against(self, &Self::specs())?;
        if self.incompressibility + self.start_pressure <= 0.0 {
            return Err(PluginError::bad_parameter(
                "start_pressure",
                format!(
                    "{} Pa below ambient is a vacuum or worse: the absolute pressure \
                     incompressibility + start_pressure must be positive (incompressibility \
                     is {} Pa)",
                    -self.start_pressure, self.incompressibility
                ),
            ));
        }
        Ok(())
    }
}

// ---------------------------------------------------------------------------------------------
// The batch of chambers
// ---------------------------------------------------------------------------------------------

/// Every chamber of a group, struct-of-arrays: the connected components of the target
/// objects' surfaces, consistently oriented (closed ones outward), with their boundary loops.
#[derive(Clone, Debug, Default)]
pub struct Chambers {
    /// Object name of each chamber.
    names: Vec<String>,
    /// Offsets into `vertices` (one more than there are chambers).
    vertex_start: Vec<usize>,
    /// Offsets into `triangles`.
    triangle_start: Vec<usize>,
    /// Offsets into `loops`.
    loop_start: Vec<usize>,
    /// Global particle index of every chamber's vertices, chamber by chamber.
    vertices: Vec<u32>,
    /// Oriented triangles, local to their chamber.
    triangles: Vec<[u32; 3]>,
    /// The same triangles in global particle indices.
    corners: Vec<[u32; 3]>,
    /// Boundary loops: ranges into `loop_vertices`.
    loops: Vec<[u32; 2]>,
    /// Local vertex indices of the loops.
    loop_vertices: Vec<u32>,
    /// The measure of each chamber in the rest pose.
    rest: Vec<Measure>,
    /// The smallest volume each chamber is taken to have (m³).
    floor: Vec<f64>,
    /// The direction every vertex moves along in this substep, `uᵢ = wᵢ gᵢ` with `gᵢ` its
    /// pressure normal at the start of the substep (m²/kg).
    directions: Vec<DVec3>,
    /// The per-vertex moments of the directions ([`Surface::line_moments`]).
    moments: Vec<DVec3>,
    /// The cubic coefficient of each chamber's volume along its directions (m³).
    cubic: Vec<f64>,
    /// The farthest any vertex of each chamber is from the chamber's centroid in the rest
    /// pose (m): no step moves a vertex farther than this (see [`Chambers::limit`]).
    reach: Vec<f64>,
    /// The longest direction `|uᵢ|` of each chamber in this substep (m²/kg).
    longest: Vec<f64>,
    /// Particle slices must hold more than this index.
    max_index: Option<u32>,
}

/// Which way an open chamber faces.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OpenOrientation {
    /// As its first triangle is wound in the scene (the user flips a sail by its winding or
    /// the sign of the pressure).
    AsGiven,
    /// So that its capped volume is positive (a bag with a hole holds its gas inside).
    PositiveVolume,
}

impl Chambers {
    /// The chambers of every target object of `scene` (each object once; objects without
    /// triangles are skipped). Closed chambers are turned outward (positive rest volume).
    pub fn new(scene: &SceneView<'_>, open: OpenOrientation) -> Result<Self, PluginError> {
        let rest_x = scene.rest_positions();
        let particles = rest_x.len().min(scene.inv_mass.len());
        let mut out = Self {
            vertex_start: vec![0],
            triangle_start: vec![0],
            loop_start: vec![0],
            ..Self::default()
        };
        for (_, object) in scene.unique_targets()? {
            for mut chamber in topology::chambers(object, particles)? {
                let measure = |c: &topology::Chamber| {
                    let loops = loop_ranges(&c.loops);
                    let flat: Vec<u32> = c.loops.concat();
                    let corners = global_corners(&c.vertices, &c.triangles);
                    Surface {
                        vertices: &c.vertices,
                        triangles: &c.triangles,
                        corners: &corners,
                        loops: &loops,
                        loop_vertices: &flat,
                    }
                    .measure(rest_x, None)
                };
                let mut rest = measure(&chamber);
                let turn = if chamber.is_closed() {
                    rest.volume < 0.0
                } else {
                    open == OpenOrientation::PositiveVolume && rest.volume < 0.0
                };
                if turn {
                    chamber.flip();
                    rest = measure(&chamber);
                }
                let area = Surface {
                    vertices: &chamber.vertices,
                    triangles: &chamber.triangles,
                    corners: &global_corners(&chamber.vertices, &chamber.triangles),
                    loops: &[],
                    loop_vertices: &[],
                }
                .area(rest_x);
                out.push(object.name.as_str(), chamber, rest, area);
            }
        }
        out.directions = vec![DVec3::ZERO; out.vertices.len()];
        out.moments = vec![DVec3::ZERO; out.vertices.len()];
        out.cubic = vec![0.0; out.len()];
        out.longest = vec![0.0; out.len()];
        out.reach = (0..out.len())
            .map(|c| {
                let vertices = &out.vertices[out.vertex_start[c]..out.vertex_start[c + 1]];
                let at = |&p: &u32| rest_x[p as usize];
                let centroid =
                    vertices.iter().map(at).sum::<DVec3>() / vertices.len().max(1) as f64;
                vertices
                    .iter()
                    .map(|p| at(p).distance(centroid))
                    .fold(0.0, f64::max)
            })
            .collect();
        Ok(out)
    }

    fn push(&mut self, name: &str, c: topology::Chamber, rest: Measure, area: f64) {
        self.names.push(name.to_string());
        self.max_index = self.max_index.max(c.vertices.last().copied());
        self.vertices.extend(&c.vertices);
        self.triangles.extend(&c.triangles);
        self.corners
            .extend(global_corners(&c.vertices, &c.triangles));
        let base = self.loop_vertices.len() as u32;
        self.loops.extend(
            loop_ranges(&c.loops)
                .iter()
                .map(|[a, b]| [a + base, b + base]),
        );
        self.loop_vertices.extend(c.loops.concat());
        self.vertex_start.push(self.vertices.len());
        self.triangle_start.push(self.triangles.len());
        self.loop_start.push(self.loops.len());
        self.floor
            .push((VOLUME_FLOOR * area.powf(1.5)).max(f64::MIN_POSITIVE));
        self.rest.push(rest);
    }

    /// Number of chambers.
    pub fn len(&self) -> usize {
        self.names.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.names.is_empty()
    }

    /// The surface of chamber `c`.
    pub fn surface(&self, c: usize) -> Surface<'_> {
        Surface {
            vertices: &self.vertices[self.vertex_start[c]..self.vertex_start[c + 1]],
            triangles: &self.triangles[self.triangle_start[c]..self.triangle_start[c + 1]],
            corners: &self.corners[self.triangle_start[c]..self.triangle_start[c + 1]],
            loops: &self.loops[self.loop_start[c]..self.loop_start[c + 1]],
            loop_vertices: &self.loop_vertices,
        }
    }

    /// Whether chamber `c` is closed.
    pub fn is_closed(&self, c: usize) -> bool {
        self.loop_start[c] == self.loop_start[c + 1]
    }

    /// The object chamber `c` belongs to.
    pub fn name(&self, c: usize) -> &str {
        &self.names[c]
    }

    /// The rest measure of chamber `c`.
    pub fn rest(&self, c: usize) -> Measure {
        self.rest[c]
    }

    /// The smallest volume chamber `c` is taken to have (m³).
    pub fn floor(&self, c: usize) -> f64 {
        self.floor[c]
    }

    /// Measures chamber `c` at `x` (no normals).
    pub fn measure(&self, c: usize, x: &[DVec3]) -> Measure {
        self.surface(c).measure(x, None)
    }

    /// At the start of a substep: computes chamber `c`'s pressure normals `gᵢ` at `x`, keeps
    /// the directions `uᵢ = wᵢ gᵢ` its vertices will move along and their moments, and
    /// returns the measure at `x`.
    fn freeze(&mut self, c: usize, x: &[DVec3], w: &[f64]) -> Measure {
        let range = self.vertex_start[c]..self.vertex_start[c + 1];
        let mut directions = std::mem::take(&mut self.directions);
        let mut moments = std::mem::take(&mut self.moments);
        let surface = self.surface(c);
        let u = &mut directions[range.clone()];
        let m = surface.measure(x, Some(u));
        surface.weight(u, w);
        let longest = u.iter().map(|u| u.length()).fold(0.0, f64::max);
        self.cubic[c] = surface.line_moments(u, &mut moments[range]);
        self.longest[c] = longest;
        self.directions = directions;
        self.moments = moments;
        m
    }

    /// Chamber `c`'s volume along its directions from `x`: `V(x + t u)` as a cubic in `t`.
    fn along(&self, c: usize, x: &[DVec3]) -> Cubic {
        let range = self.vertex_start[c]..self.vertex_start[c + 1];
        self.surface(c).volume_along(
            x,
            &self.directions[range.clone()],
            &self.moments[range],
            self.cubic[c],
        )
    }

    /// `t` limited so that a step `uᵢ t` moves no vertex of chamber `c` farther than its rest
    /// radius (the farthest a vertex is from the centroid at rest).
    ///
    /// A chamber collapsed to (near) a point has normals `gᵢ` of the size of its tiny
    /// triangles, so the step that restores its volume along them is enormous: a balloon
    /// collapsed within 1e-9 m flung vertices at 400 m/s with a hard volume and to infinity
    /// with gas. Re-inflating never needs a vertex to move farther than from the centre to its
    /// rest place, so a longer step is cut there (in the direction the step asked for) and the
    /// next passes and substeps go on from where it got to.
    pub fn limit(&self, c: usize, t: f64) -> f64 {
        let longest = self.longest[c];
        if longest * t.abs() <= self.reach[c] {
            t
        } else {
            (self.reach[c] / longest).copysign(t)
        }
    }

    /// Moves chamber `c`'s dynamic vertices by `uᵢ t` (positions; or velocities, with `t` a
    /// pressure times `h`).
    fn displace(&self, c: usize, x: &mut [DVec3], w: &[f64], t: f64) {
        let range = self.vertex_start[c]..self.vertex_start[c + 1];
        self.surface(c).displace(x, &self.directions[range], w, t);
    }
}

/// The triangles in global particle indices.
fn global_corners(vertices: &[u32], triangles: &[[u32; 3]]) -> Vec<[u32; 3]> {
    triangles
        .iter()
        .map(|t| t.map(|l| vertices[l as usize]))
        .collect()
}

/// `[start, end)` of each loop in the concatenation of `loops`.
fn loop_ranges(loops: &[Vec<u32>]) -> Vec<[u32; 2]> {
    let mut at = 0u32;
    loops
        .iter()
        .map(|l| {
            let r = [at, at + l.len() as u32];
            at = r[1];
            r
        })
        .collect()
}

/// `Σ aᵢ vᵢ / Σ vᵢ`, or the plain mean if the weights do not sum to a positive number.
fn weighted_mean(values: impl Iterator<Item = (f64, f64)> + Clone) -> f64 {
    let (sum, weight) = values
        .clone()
        .fold((0.0, 0.0), |(s, w), (a, v)| (s + a * v, w + v));
    if weight > 0.0 {
        sum / weight
    } else {
        let (sum, count) = values.fold((0.0, 0usize), |(s, k), (a, _)| (s + a, k + 1));
        if count > 0 {
            sum / count as f64
        } else {
            0.0
        }
    }
}

// ---------------------------------------------------------------------------------------------
// `pressure`: manual pressure
// ---------------------------------------------------------------------------------------------

/// All the chambers of one `pressure` group: a volume constraint on each closed chamber, a
/// constant pressure force on each open one.
#[derive(Clone, Debug)]
pub struct PressureGroup {
    chambers: Chambers,
    params: PressureParams,
    /// Target volume of each chamber (m³; closed chambers only).
    target: Vec<f64>,
    /// Compliance of each chamber's constraint (m³/Pa).
    alpha: Vec<f64>,
    /// Multiplier of each chamber accumulated in this substep (Pa·s²).
    lambda: Vec<f64>,
    /// Gauge pressure each closed chamber applied over the last substep, `λ/h²` (Pa).
    applied: Vec<f64>,
    /// Gauge pressure each chamber pushes with in the force stage (Pa): the `pressure`
    /// parameter on an open chamber; on a closed compliant one what it applied over the last
    /// substep, its `λ`'s warm start; 0 on a hard one.
    warm: Vec<f64>,
}

impl PressureGroup {
    /// The chambers of the target objects of `scene` and their targets.
    pub fn new(params: &PressureParams, scene: &SceneView<'_>) -> Result<Self, PluginError> {
        params.validate()?;
        let chambers = Chambers::new(scene, OpenOrientation::AsGiven)?;
        let n = chambers.len();
        let target = (0..n)
            .map(|c| params.pressure_scale * chambers.rest(c).volume)
            .collect();
        let alpha = (0..n)
            .map(|c| params.compliance * chambers.rest(c).volume.abs())
            .collect();
        Ok(Self {
            chambers,
            params: *params,
            target,
            alpha,
            lambda: vec![0.0; n],
            applied: vec![0.0; n],
            warm: vec![0.0; n],
        })
    }

    /// The chambers.
    pub fn chambers(&self) -> &Chambers {
        &self.chambers
    }

    /// Target volume of each chamber (m³; meaningful for closed chambers).
    pub fn targets(&self) -> &[f64] {
        &self.target
    }

    /// The volume chamber `c` is driven to: `V_target + α p` (closed chambers).
    fn goal(&self, c: usize) -> f64 {
        self.target[c] + self.alpha[c] * self.params.pressure
    }

    /// The gauge pressure chamber `c` applied in the last substep (Pa).
    fn applied(&self, c: usize) -> f64 {
        if self.chambers.is_closed(c) {
            self.applied[c]
        } else {
            self.params.pressure
        }
    }
}

impl ConstraintGroup for PressureGroup {
    fn stages(&self) -> Stages {
        Stages::FORCE | Stages::BEGIN_SUBSTEP | Stages::PROJECT | Stages::REPORT
    }

    fn len(&self) -> usize {
        self.chambers.len()
    }

    /// Freezes every chamber's normals at the start of the substep and pushes with a
    /// pressure, `vᵢ += h wᵢ p gᵢ`: on an open chamber the `pressure` parameter; on a closed
    /// compliant one the pressure it applied over the last substep (the warm start of its
    /// `λ`); a hard one pushes only in `project`.
    fn force(&mut self, ctx: &mut SolveContext<'_>) -> Result<(), PluginError> {
        let h = ctx.substep_length()?;
        ctx.check_holds(self.chambers.max_index)?;
        let p = ctx.particles();
        for c in 0..self.chambers.len() {
            self.chambers.freeze(c, p.x, p.inv_mass);
            let pressure = if !self.chambers.is_closed(c) {
                self.params.pressure
            } else if self.alpha[c] > 0.0 {
                self.applied[c]
            } else {
                0.0
            };
            // The push moves the prediction by h² p uᵢ: limited like every step.
            let pressure = self.chambers.limit(c, h * h * pressure) / (h * h);
            self.warm[c] = pressure;
            if pressure != 0.0 {
                // A velocity change w g s with s = h p.
                self.chambers.displace(c, p.v, p.inv_mass, h * pressure);
            }
        }
        Ok(())
    }

    /// Starts each closed chamber's `λ` at the impulse the force stage applied, `h² p`
    /// (the prediction carries it): `λ` is the total multiplier of the substep.
    fn begin_substep(&mut self, ctx: &mut SolveContext<'_>) -> Result<(), PluginError> {
        let h2 = ctx.h * ctx.h;
        for (lambda, warm) in self.lambda.iter_mut().zip(&self.warm) {
            *lambda = h2 * warm;
        }
        Ok(())
    }

    /// One XPBD step of each closed chamber's volume constraint, in chamber order: the volume
    /// at the current positions, the normals frozen at the start of the substep.
    fn project(&mut self, ctx: &mut SolveContext<'_>) -> Result<(), PluginError> {
        let h = ctx.substep_length()?;
        ctx.check_holds(self.chambers.max_index)?;
        let p = ctx.particles();
        for c in 0..self.chambers.len() {
            if !self.chambers.is_closed(c) {
                continue;
            }
            let line = self.chambers.along(c, p.x);
            let dl =
                solve::volume_step_along(&line, self.goal(c), self.alpha[c], self.lambda[c], h);
            let dl = self.chambers.limit(c, dl);
            self.chambers.displace(c, p.x, p.inv_mass, dl);
            self.lambda[c] += dl;
            self.applied[c] = self.lambda[c] / (h * h);
        }
        Ok(())
    }

    /// `|V − V_goal| / |V_goal|` of each closed chamber (relative volume), and the energy
    /// `½ C²/α` of the compliant ones (J). Open chambers carry no constraint.
    fn residual(&self, ctx: &SolveContext<'_>) -> Residual {
        let x = ctx.positions();
        let mut out = Residual::default();
        if ctx.check_holds(self.chambers.max_index).is_err() {
            return out;
        }
        let mut sum_sq = 0.0;
        for c in (0..self.chambers.len()).filter(|&c| self.chambers.is_closed(c)) {
            let v = self.chambers.measure(c, x).volume;
            let goal = self.goal(c);
            let err = (v - goal).abs() / goal.abs().max(self.chambers.floor(c));
            out.count += 1;
            out.max = out.max.max(err);
            sum_sq += err * err;
            if self.alpha[c] > 0.0 {
                out.energy += 0.5 * (v - goal).powi(2) / self.alpha[c];
            }
        }
        if out.count > 0 {
            out.rms = (sum_sq / out.count as f64).sqrt();
        }
        out
    }

    /// `volume` (m³, all chambers), `target_volume` (m³, closed chambers' goals) and
    /// `applied_pressure` (Pa, the gauge pressure applied in the last substep, averaged over
    /// the chambers weighted by volume).
    fn report(&self, ctx: &SolveContext<'_>, out: &mut Vec<(String, f64)>) {
        let x = ctx.positions();
        if ctx.check_holds(self.chambers.max_index).is_err() {
            return;
        }
        let volumes: Vec<f64> = (0..self.chambers.len())
            .map(|c| self.chambers.measure(c, x).volume)
            .collect();
        let targets: f64 = (0..self.chambers.len())
            .filter(|&c| self.chambers.is_closed(c))
            .map(|c| self.goal(c))
            .sum();
        let applied = weighted_mean(
            volumes
                .iter()
                .enumerate()
                .map(|(c, &v)| (self.applied(c), v)),
        );
        out.push(("volume".into(), volumes.iter().sum()));
        out.push(("target_volume".into(), targets));
        out.push(("applied_pressure".into(), applied));
    }
}

// ---------------------------------------------------------------------------------------------
// `gas`: the volume tracking model
// ---------------------------------------------------------------------------------------------

/// All the chambers of one `gas` group, each holding an ideal gas.
#[derive(Clone, Debug)]
pub struct GasGroup {
    chambers: Chambers,
    params: GasParams,
    /// Amount of gas in each chamber, `n = pV` (Pa·m³).
    amount: Vec<f64>,
    /// Multiplier of each chamber accumulated in this substep (Pa·s²).
    lambda: Vec<f64>,
    /// Gauge pressure each chamber applied over the last substep, `λ/h²` (Pa).
    applied: Vec<f64>,
    /// Gauge pressure each chamber pushes with in the force stage (Pa): what it applied over
    /// the last substep, its `λ`'s warm start.
    warm: Vec<f64>,
    /// Amount of gas in each chamber at the start of the substep, pump included (Pa·m³).
    start_amount: Vec<f64>,
    /// The leak of each chamber over the substep as a volume of ambient air, `h L` (m³).
    leak_volume: Vec<f64>,
}

impl GasGroup {
    /// The chambers of the target objects of `scene`, each filled with gas at
    /// `incompressibility + start_pressure` (absolute) in its rest volume.
    pub fn new(params: &GasParams, scene: &SceneView<'_>) -> Result<Self, PluginError> {
        params.validate()?;
        let chambers = Chambers::new(scene, OpenOrientation::PositiveVolume)?;
        let p0 = params.incompressibility + params.start_pressure;
        let n = chambers.len();
        let amount: Vec<f64> = (0..n)
            .map(|c| p0 * chambers.rest(c).volume.max(chambers.floor(c)))
            .collect();
        Ok(Self {
            chambers,
            params: *params,
            start_amount: amount.clone(),
            amount,
            lambda: vec![0.0; n],
            applied: vec![0.0; n],
            warm: vec![0.0; n],
            leak_volume: vec![0.0; n],
        })
    }

    /// The chambers.
    pub fn chambers(&self) -> &Chambers {
        &self.chambers
    }

    /// The amount of gas in each chamber, `n = pV` (Pa·m³).
    pub fn amounts(&self) -> &[f64] {
        &self.amount
    }

    /// Ambient absolute pressure (Pa).
    fn ambient(&self) -> f64 {
        self.params.incompressibility
    }

    /// The volume of chamber `c` at `x`, floored, and its measure.
    fn volume(&self, c: usize, x: &[DVec3]) -> (f64, Measure) {
        let m = self.chambers.measure(c, x);
        (m.volume.max(self.chambers.floor(c)), m)
    }

    /// The absolute pressure chamber `c` applied in the last substep (Pa).
    fn applied_absolute(&self, c: usize) -> f64 {
        self.ambient() + self.applied[c]
    }
}

impl ConstraintGroup for GasGroup {
    fn stages(&self) -> Stages {
        Stages::FORCE | Stages::BEGIN_SUBSTEP | Stages::PROJECT | Stages::REPORT
    }

    fn len(&self) -> usize {
        self.chambers.len()
    }

    /// At the start of the substep: freezes every chamber's normals, pumps its gas, sets the
    /// leak of the substep from the openings and pressure there, and pushes with the gauge
    /// pressure it applied over the last substep, `vᵢ += h wᵢ p gᵢ` (the warm start of its
    /// `λ`).
    fn force(&mut self, ctx: &mut SolveContext<'_>) -> Result<(), PluginError> {
        let h = ctx.substep_length()?;
        ctx.check_holds(self.chambers.max_index)?;
        let p = ctx.particles();
        let GasParams {
            pump_rate,
            air_tightness,
            ..
        } = self.params;
        let ambient = self.ambient();
        for c in 0..self.chambers.len() {
            let m = self.chambers.freeze(c, p.x, p.inv_mass);
            let v = m.volume.max(self.chambers.floor(c));
            let n = (self.amount[c] + pump_rate * h).max(0.0);
            self.amount[c] = n;
            self.start_amount[c] = n;
            let upwind = (n / v).max(ambient);
            self.leak_volume[c] = h * solve::leak_conductance(m.open_area, air_tightness, upwind);
            // The push moves the prediction by h² p uᵢ: limited like every step.
            let gauge = self.chambers.limit(c, h * h * self.applied[c]) / (h * h);
            self.warm[c] = gauge;
            if gauge != 0.0 {
                self.chambers.displace(c, p.v, p.inv_mass, h * gauge);
            }
        }
        Ok(())
    }

    /// Starts each chamber's `λ` at the impulse the force stage applied, `h² p`: `λ` is the
    /// total multiplier of the substep.
    fn begin_substep(&mut self, ctx: &mut SolveContext<'_>) -> Result<(), PluginError> {
        let h2 = ctx.h * ctx.h;
        for (lambda, warm) in self.lambda.iter_mut().zip(&self.warm) {
            *lambda = h2 * warm;
        }
        Ok(())
    }

    /// One implicit Newton step of each chamber's gas, in chamber order: the volume at the
    /// current positions, the normals frozen at the start of the substep.
    fn project(&mut self, ctx: &mut SolveContext<'_>) -> Result<(), PluginError> {
        let h = ctx.substep_length()?;
        ctx.check_holds(self.chambers.max_index)?;
        let p = ctx.particles();
        let ambient = self.ambient();
        for c in 0..self.chambers.len() {
            let line = self.chambers.along(c, p.x);
            let floor = self.chambers.floor(c);
            // Backward Euler on the leak: for the substep the chamber holds the gas n + p_atm hL
            // in the volume V + hL (see `solve::leaked_amount`).
            let hl = self.leak_volume[c];
            let held = self.start_amount[c] + ambient * hl;
            let solved = solve::gas_step_along(&line, floor, held, hl, ambient, self.lambda[c], h);
            let dl = self.chambers.limit(c, solved);
            self.chambers.displace(c, p.x, p.inv_mass, dl);
            self.lambda[c] += dl;
            // The gas left at the volume this step moves the chamber to.
            let moved = line.at(dl).max(floor);
            self.amount[c] = solve::leaked_amount(self.start_amount[c], moved, ambient, hl);
            self.applied[c] = if dl == solved {
                self.lambda[c] / (h * h)
            } else {
                // A cut step does not reach the root, where λ/h² is the gas's pressure: the
                // chamber pushed with no more than the gas's pressure where the step ended.
                (self.lambda[c] / (h * h)).min(held / (moved + hl) - ambient)
            };
        }
        Ok(())
    }

    /// For each chamber, `|V − V*| / V*` with `V* = n / p_applied` the volume at which the
    /// gas would push with the pressure the last substep applied: `|p_applied − p| / p`
    /// (relative volume). `energy` is the work the gas can still do expanding or
    /// contracting to ambient pressure (J).
    fn residual(&self, ctx: &SolveContext<'_>) -> Residual {
        let x = ctx.positions();
        let mut out = Residual::default();
        if ctx.check_holds(self.chambers.max_index).is_err() {
            return out;
        }
        let mut sum_sq = 0.0;
        for c in 0..self.chambers.len() {
            let (v, _) = self.volume(c, x);
            let n = self.amount[c];
            let pressure = n / v;
            let err = if pressure > 0.0 {
                (self.applied_absolute(c) - pressure).abs() / pressure
            } else {
                0.0
            };
            out.count += 1;
            out.max = out.max.max(err);
            sum_sq += err * err;
            out.energy += solve::gas_energy(v, n, self.ambient());
        }
        if out.count > 0 {
            out.rms = (sum_sq / out.count as f64).sqrt();
        }
        out
    }

    /// `volume` (m³), `amount` (Pa·m³), `pressure` (absolute, `Σn / ΣV`, Pa),
    /// `gauge_pressure` (`pressure − incompressibility`, Pa), `applied_pressure` (the gauge
    /// pressure the last substep applied, volume-weighted, Pa) and `open_area` (m²), over all
    /// the group's chambers.
    fn report(&self, ctx: &SolveContext<'_>, out: &mut Vec<(String, f64)>) {
        let x = ctx.positions();
        if ctx.check_holds(self.chambers.max_index).is_err() {
            return;
        }
        let measured: Vec<(f64, Measure)> = (0..self.chambers.len())
            .map(|c| self.volume(c, x))
            .collect();
        let volume: f64 = measured.iter().map(|(v, _)| v).sum();
        let amount: f64 = self.amount.iter().sum();
        let pressure = if volume > 0.0 { amount / volume } else { 0.0 };
        let applied = weighted_mean(
            measured
                .iter()
                .enumerate()
                .map(|(c, (v, _))| (self.applied[c], *v)),
        );
        out.push(("volume".into(), volume));
        out.push(("amount".into(), amount));
        out.push(("pressure".into(), pressure));
        out.push(("gauge_pressure".into(), pressure - self.ambient()));
        out.push(("applied_pressure".into(), applied));
        out.push((
            "open_area".into(),
            measured.iter().map(|(_, m)| m.open_area).sum(),
        ));
    }
}

/// The factory of the `pressure` kind.
pub(crate) fn build_pressure(
    params_json: &str,
    scene: &SceneView<'_>,
) -> Result<Box<dyn ConstraintGroup>, PluginError> {
    let params: PressureParams = params::parse(params_json)?;
    Ok(Box::new(PressureGroup::new(&params, scene)?))
}

/// The factory of the `gas` kind.
pub(crate) fn build_gas(
    params_json: &str,
    scene: &SceneView<'_>,
) -> Result<Box<dyn ConstraintGroup>, PluginError> {
    let params: GasParams = params::parse(params_json)?;
    Ok(Box::new(GasGroup::new(&params, scene)?))
}
