//! The `air` group through the SDK, in-process, exactly as the host drives it: created by
//! `nucleus_plugin().create_group` from JSON parameters and a hand-built scene view, and
//! called through the ABI trait object; and whole scenes through `nucleus-core` with the
//! plugin registered in-process.

use nucleus_sdk::abi_stable::std_types::RSlice;
use nucleus_sdk::prelude::*;
use nucleus_sdk::testing::CoreState;
use nucleus_sdk::GroupBox;

use crate::{nucleus_plugin, AirGroup, AirParams};

const H: f64 = 1.0 / 600.0;

/// One object: particles with rest positions and inverse masses, and its simplices.
#[derive(Clone, Default)]
struct Mesh {
    rest: Vec<[f64; 3]>,
    inv_mass: Vec<f64>,
    points: Vec<u32>,
    edges: Vec<[u32; 2]>,
    edge_triangle_count: Vec<u32>,
    triangles: Vec<[u32; 3]>,
    triangle_tet_count: Vec<u32>,
}

impl Mesh {
    /// A flat `size × size` square in the xz-plane (normal +y for the winding used), of
    /// `cells × cells` quads split into two triangles, unit masses.
    fn plate(cells: u32, size: f64) -> Self {
        let n = cells + 1;
        let rest = (0..n * n)
            .map(|k| {
                let (r, c) = (k / n, k % n);
                [
                    size * c as f64 / cells as f64,
                    0.0,
                    size * r as f64 / cells as f64,
                ]
            })
            .collect();
        let mut triangles = Vec::new();
        for r in 0..cells {
            for c in 0..cells {
                let a = r * n + c;
                triangles.push([a, a + n + 1, a + 1]);
                triangles.push([a, a + n, a + n + 1]);
            }
        }
        let mut edges: Vec<[u32; 2]> = triangles
            .iter()
            .flat_map(|t| [[t[0], t[1]], [t[1], t[2]], [t[2], t[0]]])
            .map(|[a, b]| [a.min(b), a.max(b)])
            .collect();
        edges.sort_unstable();
        edges.dedup();
        let edge_triangle_count = edges
            .iter()
            .map(|e| {
                triangles
                    .iter()
                    .filter(|t| t.contains(&e[0]) && t.contains(&e[1]))
                    .count() as u32
            })
            .collect();
        Self {
            inv_mass: vec![1.0; (n * n) as usize],
            rest,
            edges,
            edge_triangle_count,
            triangle_tet_count: vec![0; triangles.len()],
            triangles,
            ..Self::default()
        }
    }

    /// A polyline of `segments` edges along y from the origin, unit masses.
    fn rope(segments: u32, length: f64) -> Self {
        Self {
            rest: (0..=segments)
                .map(|k| [0.0, length * k as f64 / segments as f64, 0.0])
                .collect(),
            inv_mass: vec![1.0; segments as usize + 1],
            edges: (0..segments).map(|k| [k, k + 1]).collect(),
            edge_triangle_count: vec![0; segments as usize],
            ..Self::default()
        }
    }

    /// `count` unconnected particles along x.
    fn particles(count: u32) -> Self {
        Self {
            rest: (0..count).map(|k| [k as f64, 0.0, 0.0]).collect(),
            inv_mass: vec![1.0; count as usize],
            points: (0..count).collect(),
            ..Self::default()
        }
    }

    fn object(&self) -> ObjectView<'_> {
        ObjectView {
            points: RSlice::from_slice(&self.points),
            edges: RSlice::from_slice(&self.edges),
            edge_triangle_count: RSlice::from_slice(&self.edge_triangle_count),
            triangles: RSlice::from_slice(&self.triangles),
            triangle_tet_count: RSlice::from_slice(&self.triangle_tet_count),
            ..ObjectView::new("thing", 0, self.rest.len() as u32)
        }
    }

    fn with_scene<R>(&self, targets: &[u32], f: impl FnOnce(&SceneView<'_>) -> R) -> R {
        let objects = [self.object()];
        let scene = SceneView {
            gravity: [0.0, -9.81, 0.0],
            substeps: 10,
            ..SceneView::new(&objects, targets, &self.rest, &self.inv_mass)
        };
        f(&scene)
    }

    /// The `air` group of this mesh, through the plugin's ABI entry.
    fn group(&self, params: &str) -> Result<GroupBox, PluginError> {
        self.with_scene(&[0], |scene| {
            nucleus_plugin().create_group("air", params, scene)
        })
    }

    /// The group as its Rust type, to read its totals.
    fn air(&self, params: AirParams) -> AirGroup {
        self.with_scene(&[0], |scene| AirGroup::new(&params, scene))
            .expect("group")
    }
}

/// The particle state the core would own for `mesh` at rest: the SDK's [`CoreState`], with
/// substeps of [`H`] and gravity −9.81 m/s² along −y (which the air's forces never read).
fn core_state(mesh: &Mesh) -> CoreState {
    let mut state = CoreState::at_rest(mesh.rest.clone(), mesh.inv_mass.clone(), H);
    state.gravity = [0.0, -9.81, 0.0];
    state
}

/// The substep these tests take.
trait Substep {
    /// A substep without constraints: the air's force stage, then free flight.
    fn substep(&mut self, group: &mut GroupBox);
}

impl Substep for CoreState {
    fn substep(&mut self, group: &mut GroupBox) {
        self.force(group);
        for (x, v) in self.x.iter_mut().zip(&self.v) {
            for k in 0..3 {
                x[k] += H * v[k];
            }
        }
        self.time += H;
    }
}

fn bad_parameter(params: &str) -> PluginError {
    match Mesh::plate(1, 1.0).group(params) {
        Ok(_) => panic!("{params} was accepted"),
        Err(e) => e,
    }
}

fn params(json: &str) -> AirParams {
    nucleus_sdk::params::parse(
        &nucleus_sdk::params::validate_json(json, &crate::kinds()[0].param_infos()).expect("valid"),
    )
    .expect("parse")
}

#[test]
fn kind_describes_itself() {
    let info = nucleus_plugin().info();
    assert_eq!(info.name.as_str(), "air");
    let [kind] = info.kinds.as_slice() else {
        panic!("one kind expected");
    };
    assert_eq!(kind.name.as_str(), "air");
    assert_eq!(kind.residual_unit.as_str(), "m/s");
    let names: Vec<&str> = kind.params.iter().map(|p| p.name.as_str()).collect();
    assert_eq!(
        names,
        [
            "drag",
            "lift",
            "tangential_drag",
            "air_density",
            "wind_speed",
            "wind_direction",
            "noise",
            "noise_frequency",
            "noise_scale",
            "seed",
            "curve_width",
            "particle_radius"
        ]
    );
    for p in kind.params.iter() {
        assert!(!p.doc.is_empty(), "{} has no doc", p.name);
    }
    let default = |name: &str| {
        kind.params
            .iter()
            .find(|p| p.name.as_str() == name)
            .map(|p| p.default.to_string())
    };
    // Maya's nCloth and nucleus defaults, with a physical air density.
    assert_eq!(default("drag").as_deref(), Some("0.05"));
    assert_eq!(default("lift").as_deref(), Some("0.0"));
    assert_eq!(default("tangential_drag").as_deref(), Some("0.1"));
    assert_eq!(default("air_density").as_deref(), Some("1.2"));
    assert_eq!(default("wind_speed").as_deref(), Some("0.0"));
    assert_eq!(default("wind_direction").as_deref(), Some("[1.0,0.0,0.0]"));
    assert_eq!(params("{}"), AirParams::default());
}

#[test]
fn zero_wind_direction_is_rejected_naming_it() {
    let e = bad_parameter(r#"{"wind_direction": [0, 0, 0]}"#);
    assert_eq!(e.code, PluginError::BAD_PARAMETER);
    assert_eq!(e.subject.as_str(), "wind_direction");
    let e = bad_parameter(r#"{"wind_direction": [1e-300, 0, 0]}"#);
    assert_eq!(e.subject.as_str(), "wind_direction");
}

#[test]
fn bad_parameters_are_rejected_naming_them() {
    for (json, name) in [
        (r#"{"drag": -0.1}"#, "drag"),
        (r#"{"lift": "lots"}"#, "lift"),
        (r#"{"air_density": -1}"#, "air_density"),
        (r#"{"wind_speed": -3}"#, "wind_speed"),
        (r#"{"noise_scale": 0}"#, "noise_scale"),
        (r#"{"seed": -1}"#, "seed"),
        (r#"{"seed": 1.5}"#, "seed"),
        (r#"{"curve_width": -0.01}"#, "curve_width"),
        (r#"{"wind": 3}"#, "wind"),
    ] {
        let e = bad_parameter(json);
        assert_eq!(e.code, PluginError::BAD_PARAMETER, "{json}");
        assert_eq!(e.subject.as_str(), name, "{json}");
    }
    // Parameters built in Rust go through the same checks.
    let p = AirParams {
        noise: f64::NAN,
        ..AirParams::default()
    };
    let e = Mesh::plate(1, 1.0)
        .with_scene(&[0], |scene| AirGroup::new(&p, scene))
        .expect_err("NaN accepted");
    assert_eq!(e.subject.as_str(), "noise");
}

#[test]
fn group_takes_surface_triangles_curve_edges_and_points() {
    let mut mesh = Mesh::plate(2, 1.0);
    // One more triangle inside a solid (shared by two tets): the air never sees it.
    mesh.triangles.push([0, 1, 3]);
    mesh.triangle_tet_count.push(2);
    // A curve edge and an isolated point added to the object.
    let n = mesh.rest.len() as u32;
    mesh.rest
        .extend([[0.0, 1.0, 0.0], [0.0, 2.0, 0.0], [5.0, 5.0, 5.0]]);
    mesh.inv_mass.extend([1.0; 3]);
    mesh.edges.push([n, n + 1]);
    mesh.edge_triangle_count.push(0);
    mesh.points.push(n + 2);
    let group = mesh.air(AirParams::default());
    assert_eq!(group.triangles().count(), 8);
    assert_eq!(group.edges().collect::<Vec<_>>(), [[n, n + 1]]);
    assert_eq!(group.points().collect::<Vec<_>>(), [n + 2]);
    let boxed = mesh.group("{}").expect("group");
    assert_eq!(boxed.constraint_count(), 10);
    assert_eq!(boxed.stages(), Stages::FORCE | Stages::REPORT);
}

#[test]
fn mismatched_simplex_counts_are_a_bad_object() {
    let mut mesh = Mesh::plate(1, 1.0);
    mesh.edge_triangle_count.pop();
    let e = mesh.group("{}").err().expect("accepted");
    assert_eq!(e.code, PluginError::BAD_OBJECT);
    assert_eq!(e.subject.as_str(), "thing");
    let mut mesh = Mesh::plate(1, 1.0);
    mesh.triangles.push([0, 1, 9]);
    mesh.triangle_tet_count.push(0);
    let e = mesh.group("{}").err().expect("accepted");
    assert_eq!(e.code, PluginError::BAD_OBJECT);
}

#[test]
fn force_stage_changes_velocities_only_and_never_kinematic_particles() {
    let mut mesh = Mesh::plate(2, 1.0);
    mesh.inv_mass[0] = 0.0;
    let mut group = mesh
        .group(r#"{"drag": 1.0, "lift": 0.5, "wind_speed": 10, "wind_direction": [0, 1, 1]}"#)
        .expect("group");
    let mut state = core_state(&mesh);
    let x = state.x.clone();
    state.force(&mut group);
    assert_eq!(state.x, x);
    assert_eq!(state.v[0], [0.0; 3]);
    assert!(state.v[4][1] > 0.0, "{:?}", state.v[4]);
}

#[test]
fn velocity_changes_add_up_to_the_reported_force() {
    // Σ m Δv = h F_total in the explicit limit (h → 0, where the implicit factor is 1): the
    // elements' forces are split over their vertices and nothing is lost or invented.
    // Uneven masses, a gusty wind, all three element types; with a real h the implicit
    // factor only shrinks each vertex's impulse.
    let mut mesh = Mesh::plate(3, 1.0);
    for (k, w) in mesh.inv_mass.iter_mut().enumerate() {
        *w = 1.0 / (0.01 + 0.003 * k as f64);
    }
    let n = mesh.rest.len() as u32;
    mesh.rest
        .extend([[0.0, 1.0, 0.0], [0.3, 2.0, 0.0], [5.0, 5.0, 5.0]]);
    mesh.inv_mass.extend([50.0, 60.0, 70.0]);
    mesh.edges.push([n, n + 1]);
    mesh.edge_triangle_count.push(0);
    mesh.points.push(n + 2);
    let p = params(
        r#"{"drag": 1.1, "lift": 0.7, "tangential_drag": 0.3, "wind_speed": 12,
            "wind_direction": [1, 0.5, -0.2], "noise": 3, "noise_scale": 0.4,
            "curve_width": 0.05, "particle_radius": 0.1}"#,
    );
    let momentum_change = |h: f64| {
        let mut group = mesh.air(p);
        let mut state = core_state(&mesh);
        // Tilt the plate a little so every term works.
        for (k, x) in state.x.iter_mut().enumerate() {
            x[1] = 0.1 * x[0] + 0.01 * (k % 3) as f64;
        }
        state.time = 0.7;
        let mut ctx = state.ctx();
        ctx.h = h;
        ConstraintGroup::force(&mut group, &mut ctx).expect("force");
        let momentum: DVec3 = state
            .v
            .iter()
            .zip(&state.inv_mass)
            .map(|(v, w)| DVec3::from_array(*v) / w)
            .sum();
        (momentum, h * group.totals().total())
    };
    let (dp, impulse) = momentum_change(1e-9);
    assert!(impulse.length() > 1e-9, "{impulse}");
    assert!(
        (dp - impulse).length() < 1e-6 * impulse.length(),
        "{dp} vs {impulse}"
    );
    let (dp, impulse) = momentum_change(H);
    assert!(dp.length() < impulse.length() && dp.dot(impulse) > 0.9 * impulse.length_squared());
}

#[test]
fn held_plate_reports_its_load_and_does_not_move() {
    // A fully pinned 1 m² plate face-on in a 10 m/s wind: ½ ρ C_d A U² = 60 N downwind.
    let mut mesh = Mesh::plate(2, 1.0);
    mesh.inv_mass.fill(0.0);
    let mut group = mesh
        .group(r#"{"drag": 1.0, "wind_speed": 10, "wind_direction": [0, 1, 0]}"#)
        .expect("group");
    let mut state = core_state(&mesh);
    state.force(&mut group);
    assert!(state.v.iter().flatten().all(|&c| c == 0.0));
    let report = state.report(&group);
    let get = |name: &str| {
        report
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| *v)
            .expect(name)
    };
    assert!((get("force_y") - 60.0).abs() < 1e-12, "{report:?}");
    assert!(get("force_x").abs() < 1e-12 && get("force_z").abs() < 1e-12);
    assert!((get("drag") - 60.0).abs() < 1e-12);
    assert_eq!(get("lift"), 0.0);
    assert_eq!(get("tangential"), 0.0);
    // The residual is the relative speed: 10 m/s for every triangle.
    let r = group
        .residual(&state.ctx())
        .into_result()
        .expect("residual");
    assert_eq!(r.count, 8);
    assert!(
        (r.max - 10.0).abs() < 1e-12 && (r.rms - 10.0).abs() < 1e-12,
        "{r:?}"
    );
}

#[test]
fn still_air_slows_a_moving_rope_and_particles() {
    for mesh in [Mesh::rope(4, 1.0), Mesh::particles(3)] {
        let mut group = mesh
            .group(r#"{"drag": 1.0, "curve_width": 0.1, "particle_radius": 0.2}"#)
            .expect("group");
        let mut state = core_state(&mesh);
        for v in &mut state.v {
            *v = [3.0, 0.0, 0.0];
        }
        let mut last = 3.0;
        for _ in 0..100 {
            state.substep(&mut group);
            let speed = state.v[1][0];
            assert!(speed < last && speed > 0.0, "{speed} after {last}");
            last = speed;
        }
    }
}

#[test]
fn degenerate_geometry_gives_no_nan() {
    // Every particle of a plate, a rope and a point cloud at the same place, in a gusty wind:
    // zero-area triangles and zero-length edges feel nothing; points still feel drag.
    let mut mesh = Mesh::plate(2, 1.0);
    let n = mesh.rest.len() as u32;
    mesh.rest.extend([[0.0; 3]; 3]);
    mesh.inv_mass.extend([1.0; 3]);
    mesh.edges.push([n, n + 1]);
    mesh.edge_triangle_count.push(0);
    mesh.points.push(n + 2);
    let mut group = mesh
        .group(r#"{"drag": 1, "lift": 1, "tangential_drag": 1, "wind_speed": 20, "noise": 5}"#)
        .expect("group");
    let mut state = core_state(&mesh);
    for x in &mut state.x {
        *x = [0.25, -0.5, 1.0];
    }
    for _ in 0..10 {
        state.substep(&mut group);
    }
    assert!(state.all_finite());
    // Collinear particles: zero area again.
    for (k, x) in state.x.iter_mut().enumerate() {
        *x = [k as f64 * 0.1, 0.0, 0.0];
    }
    for _ in 0..10 {
        state.substep(&mut group);
    }
    assert!(state.all_finite());
    let r = group
        .residual(&state.ctx())
        .into_result()
        .expect("residual");
    assert!(r.max.is_finite() && r.rms.is_finite());
    let report = state.report(&group);
    assert!(report.iter().all(|(_, v)| v.is_finite()), "{report:?}");
}

#[test]
fn gusty_runs_are_bit_identical_and_depend_on_the_seed() {
    let mesh = Mesh::plate(3, 1.0);
    let run = |seed: u64| {
        let mut group = mesh
            .group(&format!(
                r#"{{"drag": 1, "lift": 0.5, "wind_speed": 5, "noise": 2, "noise_frequency": 3, "seed": {seed}}}"#
            ))
            .expect("group");
        let mut state = core_state(&mesh);
        for _ in 0..50 {
            state.substep(&mut group);
        }
        state
            .x
            .iter()
            .chain(&state.v)
            .flatten()
            .map(|c| c.to_bits())
            .collect::<Vec<_>>()
    };
    assert_eq!(run(7), run(7));
    assert_ne!(run(7), run(8));
}

#[test]
fn a_state_too_small_for_the_group_is_an_error_not_a_panic() {
    let mesh = Mesh::plate(2, 1.0);
    let mut group = mesh.group("{}").expect("group");
    let mut state = core_state(&mesh);
    state.x.truncate(4);
    state.v.truncate(4);
    state.inv_mass.truncate(4);
    let e = group
        .force(&mut state.ctx())
        .into_result()
        .expect_err("ran");
    assert_eq!(e.code, PluginError::FAILED);
    let r = group
        .residual(&state.ctx())
        .into_result()
        .expect("residual");
    assert_eq!(r.count, 0);
}

#[test]
fn target_listed_twice_is_used_once() {
    let mesh = Mesh::plate(2, 1.0);
    let group = mesh
        .with_scene(&[0, 0], |scene| {
            nucleus_plugin().create_group("air", "{}", scene)
        })
        .expect("group");
    assert_eq!(group.constraint_count(), 8);
    let e = mesh
        .with_scene(&[1], |scene| {
            nucleus_plugin().create_group("air", "{}", scene)
        })
        .err()
        .expect("a missing target accepted");
    assert_eq!(e.code, PluginError::FAILED);
}

/// A whole scene through `nucleus-core`, the plugin registered in-process.
fn simulation(toml: &str) -> nucleus_core::Simulation {
    let mut reg = nucleus_core::Registry::default();
    reg.add_in_process(nucleus_plugin());
    nucleus_core::Simulation::from_toml(toml, &reg).unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn falling_particles_reach_the_sphere_terminal_velocity() {
    // v_t = sqrt(2 m g / (ρ C_d π r²)); 10 g, r = 5 cm, C_d = 0.47: 9.45 m/s.
    let mut sim = simulation(
        r#"
[solver]
frame_rate = 60.0
substeps = 10
[[objects]]
name = "drops"
vertex_mass = 0.01
[objects.particles]
min = [0.0, 0.0, 0.0]
max = [1.0, 0.0, 0.0]
count = [3, 1, 1]
[[constraints]]
kind = "air"
params = { drag = 0.47, particle_radius = 0.05 }
"#,
    );
    let vt = (2.0 * 0.01 * 9.81 / (1.2 * 0.47 * std::f64::consts::PI * 0.0025)).sqrt();
    for _ in 0..300 {
        sim.step_frame().expect("step");
    }
    for v in sim.velocities() {
        assert!((v.y.abs() - vt).abs() < 1e-3 * vt, "{} vs {vt}", v.y);
        assert_eq!((v.x, v.z), (0.0, 0.0));
    }
}

#[test]
fn a_rope_across_the_wind_is_pushed_downwind() {
    // A horizontal rope pinned at both ends, across a horizontal wind, no gravity: it bows
    // downwind and the air's load on it is ½ ρ C_d (L b) U² at the start.
    let mut sim = simulation(
        r#"
[solver]
gravity = [0.0, 0.0, 0.0]
[[objects]]
name = "rope"
mass = 0.1
pins = ["ends"]
[objects.rope]
start = [0.0, 1.0, 0.0]
end = [2.0, 1.0, 0.0]
segments = 10
[[constraints]]
kind = "air"
params = { drag = 1.0, curve_width = 0.02, wind_speed = 5.0, wind_direction = [0.0, 0.0, 1.0] }
"#,
    );
    sim.step_frame().expect("step");
    let load = sim
        .reports()
        .expect("report")
        .into_iter()
        .find(|(n, _)| n == "air.force_z")
        .map(|(_, v)| v)
        .expect("force_z");
    let expected = 0.5 * 1.2 * 1.0 * (2.0 * 0.02) * 25.0;
    // The rope has moved for one frame: its relative speed has dropped a little.
    assert!(
        load > 0.95 * expected && load <= expected,
        "{load} vs {expected}"
    );
    let middle = sim.positions()[5];
    assert!(middle.z > 0.0, "{middle}");
}
