//! The groups in-process: built by `nucleus_plugin().create_group` from hand-made scene views
//! (for the error paths), and inside whole scenes built by `nucleus-core` with the `stretch`
//! plugin linked in (for behaviour). The workspace tests `tests/tests/bend_*.rs` repeat the
//! issue's acceptance tests through the dynamically loaded library.

use std::f64::consts::PI;
use std::path::PathBuf;

use nucleus_core::{Registry, Simulation};
use nucleus_sdk::abi_stable::std_types::RSlice;
use nucleus_sdk::prelude::*;
use nucleus_sdk::testing::CoreState;
use nucleus_sdk::{EdgePair, GroupBox, TrianglePair};

use crate::dihedral::dihedral_angle;
use crate::nucleus_plugin;

fn registry() -> Registry {
    let mut reg = Registry::default();
    reg.add_in_process(nucleus_plugin());
    reg.add_in_process(nucleus_stretch::nucleus_plugin());
    reg
}

fn sim(text: &str) -> Simulation {
    Simulation::from_toml(text, &registry()).unwrap_or_else(|e| panic!("build: {e}"))
}

/// Writes `text` to a fresh OBJ file under the system temp directory.
fn obj_file(tag: &str, text: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("nucleus-bend-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let path = dir.join(format!("{tag}.obj"));
    std::fs::write(&path, text).expect("write obj");
    path
}

fn group_index(sim: &Simulation, name: &str) -> usize {
    sim.groups
        .iter()
        .position(|g| g.name == name)
        .unwrap_or_else(|| panic!("no group {name}"))
}

fn residual(sim: &mut Simulation, name: &str) -> Residual {
    let g = group_index(sim, name);
    sim.residuals().expect("residuals")[g]
}

fn report(sim: &mut Simulation, key: &str) -> f64 {
    sim.reports()
        .expect("reports")
        .into_iter()
        .find(|(k, _)| k == key)
        .unwrap_or_else(|| panic!("no stat {key}"))
        .1
}

fn all_finite(sim: &Simulation) -> bool {
    sim.particles
        .x
        .iter()
        .chain(&sim.particles.v)
        .flatten()
        .all(|c| c.is_finite())
}

/// A scene: `[solver]` at 60 Hz with the `solver` lines, then `body` (objects and groups).
fn scene(solver: &str, body: &str) -> String {
    format!("[solver]\nframe_rate = 60.0\n{solver}\n{body}")
}

/// A 1 m, 1 kg cloth of 3 × 3 vertices in the xz plane; `extra` goes into its table.
fn grid(extra: &str) -> String {
    format!(
        "[[objects]]\nname = \"cloth\"\nmass = 1.0\n{extra}\n[objects.grid]\nsize = [1.0, 1.0]\nresolution = [3, 3]\n"
    )
}

/// A straight 1 m, 1 kg rope of 5 segments along x; `extra` goes into its table.
fn rope(extra: &str) -> String {
    format!(
        "[[objects]]\nname = \"rope\"\nmass = 1.0\n{extra}\n[objects.rope]\nstart = [0.0, 0.0, 0.0]\nend = [1.0, 0.0, 0.0]\nsegments = 5\n"
    )
}

/// An OBJ object named `name` read from `path`.
fn mesh(name: &str, path: &std::path::Path, extra: &str) -> String {
    format!("[[objects]]\nname = \"{name}\"\n{extra}\n[objects.mesh]\npath = {path:?}\n")
}

fn group(kind: &str, objects: &str, params: &str) -> String {
    let objects = if objects.is_empty() {
        String::new()
    } else {
        format!("objects = [{objects}]\n")
    };
    format!("[[constraints]]\nkind = \"{kind}\"\n{objects}params = {{ {params} }}\n")
}

/// Two triangles (0, 1, 2) and (1, 0, 3) sharing the edge 0–1 along x, wing 2 at −z, wing 3
/// turned down by `fold` (rad) about the x axis.
fn hinge_obj(fold: f64) -> String {
    let l = [0.5, -fold.sin() * 0.5, fold.cos() * 0.5];
    format!(
        "v 0 0 0\nv 1 0 0\nv 0.5 0 -0.5\nv {} {} {}\nf 1 2 3\nf 2 1 4\n",
        l[0], l[1], l[2]
    )
}

// ---------------------------------------------------------------------------------------
// Hand-made scene views: curves with any rest shape, and the factory's error paths
// ---------------------------------------------------------------------------------------

/// One object given directly as the SDK's view lists it.
#[derive(Default)]
struct Mesh {
    rest: Vec<[f64; 3]>,
    inv_mass: Vec<f64>,
    edges: Vec<[u32; 2]>,
    triangles: Vec<[u32; 3]>,
    pairs: Vec<TrianglePair>,
    edge_pairs: Vec<EdgePair>,
}

impl Mesh {
    /// A polyline through `points`, unit masses.
    fn polyline(points: &[DVec3]) -> Self {
        let n = points.len() as u32;
        Self {
            rest: points.iter().map(|p| p.to_array()).collect(),
            inv_mass: vec![1.0; n as usize],
            edges: (1..n).map(|k| [k - 1, k]).collect(),
            edge_pairs: (1..n.saturating_sub(1))
                .map(|k| EdgePair {
                    vertices: [k - 1, k, k + 1],
                })
                .collect(),
            ..Self::default()
        }
    }

    /// A helix of `segments` edges: radius 0.1 m, 12 segments and 0.05 m of rise per turn.
    fn helix(segments: u32) -> Self {
        let points: Vec<DVec3> = (0..=segments)
            .map(|k| {
                let t = k as f64 * 2.0 * PI / 12.0;
                DVec3::new(0.1 * t.cos(), 0.1 * t.sin(), 0.05 * t / (2.0 * PI))
            })
            .collect();
        Self::polyline(&points)
    }

    fn view(&self) -> ObjectView<'_> {
        ObjectView {
            edges: RSlice::from_slice(&self.edges),
            triangles: RSlice::from_slice(&self.triangles),
            triangle_pairs: RSlice::from_slice(&self.pairs),
            edge_pairs: RSlice::from_slice(&self.edge_pairs),
            ..ObjectView::new("thing", 0, self.rest.len() as u32)
        }
    }

    /// The group of `kind` (of this plugin or `stretch`), the object listed twice as target.
    fn group(&self, kind: &str, params: &str) -> Result<GroupBox, PluginError> {
        let objects = [self.view()];
        let scene = SceneView {
            substeps: 10,
            ..SceneView::new(&objects, &[0, 0], &self.rest, &self.inv_mass)
        };
        if kind == "stretch" {
            nucleus_stretch::nucleus_plugin().create_group(kind, params, &scene)
        } else {
            nucleus_plugin().create_group(kind, params, &scene)
        }
    }
}

const H: f64 = 1.0 / 600.0;

/// The particle state the core would own at `x`: the SDK's [`CoreState`], with substeps of
/// [`H`] and no gravity.
fn core_state(mesh: &Mesh, x: Vec<[f64; 3]>) -> CoreState {
    CoreState::at_rest(x, mesh.inv_mass.clone(), H)
}

/// The substep these tests take.
trait Substep {
    /// One substep as the core runs it (gravity, prediction, `begin_substep`, one pass of
    /// every group, velocity update), with velocity damping `v *= 1 − damping·h` afterwards.
    fn substep(&mut self, groups: &mut [GroupBox], damping: f64);
}

impl Substep for CoreState {
    fn substep(&mut self, groups: &mut [GroupBox], damping: f64) {
        let (h, g) = (self.h, self.gravity);
        for (v, &w) in self.v.iter_mut().zip(&self.inv_mass) {
            if w > 0.0 {
                for k in 0..3 {
                    v[k] += h * g[k];
                }
            }
        }
        self.start_substep();
        for (x, v) in self.x.iter_mut().zip(&self.v) {
            for k in 0..3 {
                x[k] += h * v[k];
            }
        }
        for g in groups.iter_mut() {
            self.begin(g);
        }
        for g in groups.iter_mut() {
            self.project(g);
        }
        for ((v, x), x0) in self.v.iter_mut().zip(&self.x).zip(&self.x0) {
            for k in 0..3 {
                v[k] = (x[k] - x0[k]) / h * (1.0 - damping * h);
            }
        }
    }
}

// ---------------------------------------------------------------------------------------
// Description, counts and parameters
// ---------------------------------------------------------------------------------------

#[test]
fn plugin_provides_four_kinds_with_compliance_in_rad_per_newton_metre() {
    let info = nucleus_plugin().info();
    assert_eq!(info.name.as_str(), "bend");
    let names: Vec<&str> = info.kinds.iter().map(|k| k.name.as_str()).collect();
    assert_eq!(names, ["bend", "bend_isometric", "shear", "twist"]);
    for kind in info.kinds.iter() {
        assert_eq!(kind.default_order, 1, "{}", kind.name);
        assert_eq!(kind.default_importance, 1);
        assert_eq!(kind.residual_unit.as_str(), "rad");
        let [p] = kind.params.as_slice() else {
            panic!("{}: one parameter expected", kind.name);
        };
        assert_eq!(p.name.as_str(), "compliance");
        assert_eq!(p.unit.as_str(), "rad/(N·m)");
        assert_eq!(p.min, 0.0);
        assert!(!p.doc.is_empty() && !kind.doc.is_empty());
    }
    let default = |k: usize| info.kinds[k].params[0].default.to_string();
    assert_eq!(default(0), "5000.0", "bend: medium cotton");
    assert_eq!(default(1), "5000.0");
    assert_eq!(default(2), "0.0", "shear: rigid, as stretch");
    assert_eq!(default(3), "5000.0");
}

#[test]
fn each_kind_builds_one_constraint_per_element_of_its_objects() {
    let body = format!(
        "{}{}{}{}{}{}",
        grid(""),
        rope(""),
        group("bend", "", ""),
        group("bend_isometric", "", ""),
        group("shear", "", ""),
        group("twist", "", "")
    );
    let mut s = sim(&scene("", &body));
    let count = |s: &Simulation, name: &str| s.groups[group_index(s, name)].len;
    // 3×3 grid: 16 edges, 8 on the boundary → 8 hinges; 8 triangles. Rope of 5 segments:
    // 4 inner vertices; 3 chains, straight, so dropped.
    assert_eq!(count(&s, "bend"), 8 + 4);
    assert_eq!(count(&s, "bend_isometric"), 8);
    assert_eq!(count(&s, "shear"), 8 * 3);
    assert_eq!(count(&s, "twist"), 0);
    assert_eq!(report(&mut s, "twist.dropped"), 3.0);
    assert_eq!(report(&mut s, "bend.dropped"), 0.0);
    // A helix of 8 segments: 7 angles, 6 chains; nothing for the surface kinds.
    let helix = Mesh::helix(8);
    let n = |kind: &str| helix.group(kind, "{}").expect("group").constraint_count();
    assert_eq!(n("bend"), 7);
    assert_eq!(n("twist"), 6);
    assert_eq!(n("shear"), 0);
    assert_eq!(n("bend_isometric"), 0);
}

#[test]
fn bad_parameters_are_rejected_naming_them() {
    for kind in ["bend", "bend_isometric", "shear", "twist"] {
        for (params, name) in [
            ("compliance = -1.0", "compliance"),
            ("stiffness = 3.0", "stiffness"),
        ] {
            let body = format!("{}{}", grid(""), group(kind, "", params));
            let err = Simulation::from_toml(&scene("", &body), &registry())
                .err()
                .expect("accepted");
            let msg = err.to_string();
            assert!(msg.contains(&format!("`{name}`")), "{msg}");
            assert!(msg.starts_with("inline.toml:"), "{msg}");
        }
    }
    let params = crate::BendParams {
        compliance: f64::NAN,
    };
    let e = params.validate(crate::Kind::Bend).unwrap_err();
    assert_eq!(e.subject.as_str(), "compliance");
}

#[test]
fn constraints_outside_their_object_or_repeating_a_particle_are_bad_objects() {
    let diamond = || Mesh {
        rest: vec![[0.0; 3], [1.0, 0.0, 0.0], [0.5, 1.0, 0.0], [0.5, -1.0, 0.0]],
        inv_mass: vec![1.0; 4],
        triangles: vec![[0, 1, 2], [1, 0, 3]],
        ..Mesh::default()
    };
    let pair = |edge: [u32; 2], opposite: [u32; 2]| TrianglePair {
        triangles: [0, 1],
        edge,
        opposite,
    };
    // Listed twice among the targets, used once.
    let mut ok = diamond();
    ok.pairs = vec![pair([0, 1], [2, 3])];
    assert_eq!(ok.group("bend", "{}").expect("valid").constraint_count(), 1);
    let cases = [
        (vec![pair([0, 1], [2, 9])], Vec::<[u32; 3]>::new(), "bend"),
        (vec![pair([0, 1], [2, 2])], vec![], "bend_isometric"),
        (vec![], vec![[0, 1, 7]], "bend"),
        (vec![], vec![[0, 1, 7]], "twist"),
        (vec![], vec![[0, 1, 0]], "bend"),
    ];
    for (pairs, edge_pairs, kind) in cases {
        let mut m = diamond();
        m.pairs = pairs;
        m.edge_pairs = edge_pairs
            .into_iter()
            .map(|vertices| EdgePair { vertices })
            .collect();
        let e = m.group(kind, "{}").err().expect("accepted");
        assert_eq!(e.code, PluginError::BAD_OBJECT, "{e}");
        assert_eq!(e.subject.as_str(), "thing");
    }
    let mut m = diamond();
    m.triangles.push([0, 1, 8]);
    let e = m.group("shear", "{}").err().expect("accepted");
    assert_eq!(e.code, PluginError::BAD_OBJECT);
}

// ---------------------------------------------------------------------------------------
// Behaviour
// ---------------------------------------------------------------------------------------

#[test]
fn rest_shape_has_zero_residual_for_every_kind() {
    let folded = obj_file("hinge-rest", &hinge_obj(2.0));
    let body = format!(
        "{}{}{}{}{}{}",
        grid(""),
        rope(""),
        mesh("fold", &folded, ""),
        group("bend", "", ""),
        group("bend_isometric", "\"cloth\"", ""),
        group("shear", "", ""),
    );
    let mut s = sim(&scene("", &body));
    for r in s.residuals().expect("residuals") {
        assert!(r.count > 0);
        assert!(r.max < 1e-12 && r.energy < 1e-12, "{r:?}");
    }
    let helix = Mesh::helix(20);
    for kind in ["bend", "twist"] {
        let g = helix.group(kind, "{}").expect("group");
        let r = core_state(&helix, helix.rest.clone()).residual(&g);
        assert_eq!(r.count, g.constraint_count());
        assert!(r.max < 1e-12 && r.energy < 1e-12, "{kind}: {r:?}");
    }
}

#[test]
fn kinematic_particles_never_move_and_fully_pinned_constraints_are_left_out() {
    let body = format!(
        "{}{}",
        rope("pins = [0, 1, 2]"),
        group("bend", "", "compliance = 0.0")
    );
    let mut s = sim(&scene("gravity = [0.0, -9.81, 0.0]", &body));
    // Angles at 1 (0-1-2, all pinned: left out), 2, 3, 4.
    assert_eq!(s.groups[0].len, 3);
    let pinned: Vec<[f64; 3]> = s.particles.x[..3].to_vec();
    for _ in 0..30 {
        s.step_frame().expect("step");
    }
    assert_eq!(&s.particles.x[..3], &pinned[..]);
    // Rigid in bending, the free end cannot fall: it stays on the line of the pinned part.
    let sag = s.particles.x[3..]
        .iter()
        .map(|p| p[1].abs())
        .fold(0.0, f64::max);
    assert!(sag < 1e-3, "sag {sag}");
}

#[test]
fn compliant_hinge_settles_where_its_torque_balances_gravity() {
    // Wing 3 (mass m, on a circle of radius r = 0.5 m about the x axis, kept there by hard
    // stretch) hangs from a flat hinge of compliance α: static equilibrium β/α = m g r cos β
    // for the droop β. This pins down the compliance's unit, rad/(N·m).
    let (m, g, r) = (0.1, 9.81, 0.5);
    let path = obj_file("hinge-statics", &hinge_obj(0.0));
    for alpha in [0.05, 0.5, 2.0] {
        let body = format!(
            "{}{}{}",
            mesh(
                "hinge",
                &path,
                &format!("vertex_mass = {m:?}\npins = [0, 1, 2]")
            ),
            group("stretch", "", ""),
            group("bend", "", &format!("compliance = {alpha:?}")),
        );
        let mut s = sim(&scene(
            &format!(
                "gravity = [0.0, {:?}, 0.0]\ndamping = 4.0\nsubsteps = 20",
                -g
            ),
            &body,
        ));
        for _ in 0..300 {
            s.step_frame().expect("step");
        }
        let x = s.positions();
        assert!(x[3].y < 0.0, "the wing hangs down");
        let droop = dihedral_angle(&[x[0], x[1], x[2], x[3]])
            .expect("regular")
            .abs();
        // Solve β = α m g r cos β by bisection.
        let (mut lo, mut hi) = (0.0, PI / 2.0);
        for _ in 0..100 {
            let mid = 0.5 * (lo + hi);
            if mid < alpha * m * g * r * f64::cos(mid) {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        assert!(
            (droop - lo).abs() < 0.005 * lo,
            "α = {alpha}: droop {droop} rad, expected {lo}"
        );
    }
}

#[test]
fn straight_rope_bent_into_an_arc_straightens_without_gravity() {
    let body = format!(
        "{}{}{}",
        rope(""),
        group("stretch", "", ""),
        group("bend", "", "compliance = 1e-3")
    );
    let mut s = sim(&scene("gravity = [0.0, 0.0, 0.0]\ndamping = 2.0", &body));
    // Bend the rope into a quarter circle of the same length.
    let n = s.particles.x.len();
    let radius = 2.0 / PI;
    for (k, p) in s.particles.x.iter_mut().enumerate() {
        let t = k as f64 / (n - 1) as f64 * PI / 2.0;
        *p = [radius * t.sin(), radius * (1.0 - t.cos()), 0.0];
    }
    let before = residual(&mut s, "bend").max;
    assert!(before > 0.3, "{before}");
    for _ in 0..240 {
        s.step_frame().expect("step");
    }
    assert!(residual(&mut s, "bend").max < 1f64.to_radians());
}

#[test]
fn twist_restores_a_disturbed_helix_which_bend_alone_cannot() {
    // Stretch and bend fix the edge lengths and the angles between consecutive edges; the
    // torsion of the centreline stays free. Only with twist does the helix come back.
    let helix = Mesh::helix(24);
    let mut disturbed = helix.rest.clone();
    for (k, p) in disturbed.iter_mut().enumerate() {
        p[2] += 0.02 * (k as f64 * 0.7).sin();
    }
    let run = |with_twist: bool| {
        let mut groups = vec![
            helix.group("stretch", "{}").expect("stretch"),
            helix.group("bend", r#"{"compliance": 0.0}"#).expect("bend"),
        ];
        if with_twist {
            groups.push(
                helix
                    .group("twist", r#"{"compliance": 0.0}"#)
                    .expect("twist"),
            );
        }
        let twist = helix.group("twist", "{}").expect("twist");
        let mut state = core_state(&helix, disturbed.clone());
        let before = state.residual(&twist).max;
        for _ in 0..600 {
            state.substep(&mut groups, 20.0);
        }
        assert!(state.x.iter().flatten().all(|c| c.is_finite()));
        (before, state.residual(&twist).max)
    };
    let (before, free) = run(false);
    let (_, restored) = run(true);
    assert!(before > 0.1, "the disturbance twists the helix: {before}");
    assert!(free > 0.05, "bend alone leaves the torsion: {free}");
    assert!(restored < 1e-3, "twist restores it: {restored}");
}

#[test]
fn a_hanging_coil_keeps_its_coils_with_twist_and_unwinds_without() {
    // scenes/rope_coil.toml in-process: a helix of 4 turns (radius 0.1 m, 12 segments per
    // turn, 5 cm pitch), 0.1 kg, clamped by its top two vertices, 4 s under gravity at 50
    // substeps per 1/60 s, bend and twist compliance 0.2 rad/(N·m).
    let points: Vec<DVec3> = (0..=48)
        .map(|k| {
            let t = 2.0 * PI * k as f64 / 12.0;
            DVec3::new(0.1 * t.cos(), -0.05 * k as f64 / 12.0, 0.1 * t.sin())
        })
        .collect();
    let mut coil = Mesh::polyline(&points);
    coil.inv_mass = vec![49.0 / 0.1; 49];
    coil.inv_mass[..2].fill(0.0);
    let hang = |with_twist: bool| {
        let params = r#"{"compliance": 0.2}"#;
        let mut groups = vec![
            coil.group("stretch", "{}").expect("stretch"),
            coil.group("bend", params).expect("bend"),
        ];
        if with_twist {
            groups.push(coil.group("twist", params).expect("twist"));
        }
        let mut state = core_state(&coil, coil.rest.clone());
        state.h = 1.0 / 3000.0;
        state.gravity = [0.0, -9.81, 0.0];
        for _ in 0..12_000 {
            state.substep(&mut groups, 0.5);
        }
        assert!(state.x.iter().flatten().all(|c| c.is_finite()));
        // Height of the hanging coil.
        let ys = state.x.iter().map(|p| p[1]);
        ys.clone().fold(f64::MIN, f64::max) - ys.fold(f64::MAX, f64::min)
    };
    let coiled = hang(true);
    let unwound = hang(false);
    // The rope is 2.5 m long; at rest the coil is 0.2 m high.
    assert!(coiled < 0.6, "with twist the coil hangs {coiled} m high");
    assert!(unwound > 1.5, "without twist it unwinds to {unwound} m");
}

#[test]
fn degenerate_states_are_skipped_and_reported_without_nan() {
    let body = format!(
        "{}{}{}{}{}",
        grid(""),
        rope(""),
        group("bend", "", ""),
        group("bend_isometric", "\"cloth\"", ""),
        group("shear", "", ""),
    );
    let mut s = sim(&scene("gravity = [0.0, -9.81, 0.0]", &body));
    // Every particle at one point: every element is degenerate.
    let p = [0.3, 0.2, 0.1];
    s.particles.x.iter_mut().for_each(|x| *x = p);
    s.step_frame().expect("step");
    assert!(all_finite(&s));
    for name in ["bend", "bend_isometric", "shear"] {
        let len = s.groups[group_index(&s, name)].len as f64;
        assert_eq!(report(&mut s, &format!("{name}.skipped")), len, "{name}");
    }
    for r in s.residuals().expect("residuals") {
        assert!(r.max.is_finite() && r.rms.is_finite() && r.energy.is_finite());
    }
    // A helix collapsed onto its axis: every twist plane is undefined.
    let helix = Mesh::helix(8);
    let mut twist = vec![helix
        .group("twist", r#"{"compliance": 0.0}"#)
        .expect("twist")];
    let line: Vec<[f64; 3]> = (0..9).map(|k| [0.0, 0.0, k as f64 * 0.01]).collect();
    let mut state = core_state(&helix, line);
    state.substep(&mut twist, 0.0);
    assert_eq!(state.stat(&twist[0], "skipped"), 6.0);
    assert!(state.x.iter().flatten().all(|c| c.is_finite()));
}

#[test]
fn degenerate_rest_elements_are_dropped_and_reported() {
    // A zero-area triangle (2 on the edge 0–1) next to a good one.
    let path = obj_file(
        "degenerate-rest",
        "v 0 0 0\nv 1 0 0\nv 0.5 0 0\nv 0.5 0 0.5\nf 1 2 3\nf 2 1 4\n",
    );
    let body = format!(
        "{}{}{}{}",
        mesh("bad", &path, ""),
        group("bend", "", ""),
        group("bend_isometric", "", ""),
        group("shear", "", ""),
    );
    let mut s = sim(&scene("gravity = [0.0, -9.81, 0.0]", &body));
    assert_eq!(s.groups[0].len, 0);
    assert_eq!(report(&mut s, "bend.dropped"), 1.0);
    assert_eq!(report(&mut s, "bend_isometric.dropped"), 1.0);
    // shear: the corners of the zero-area triangle have angles 0, 0 and π: defined, so
    // kept (skipped while collinear); only corners with a zero-length edge are dropped.
    assert_eq!(s.groups[2].len, 6);
    for _ in 0..20 {
        s.step_frame().expect("step");
    }
    assert!(all_finite(&s));
    // A curve whose first two points coincide: the angle at 1 is dropped, the one at 2 kept.
    let curve = Mesh::polyline(&[
        DVec3::ZERO,
        DVec3::ZERO,
        DVec3::X,
        DVec3::new(1.0, 1.0, 0.0),
    ]);
    let g = curve.group("bend", "{}").expect("bend");
    assert_eq!(g.constraint_count(), 1);
    assert_eq!(
        core_state(&curve, curve.rest.clone()).stat(&g, "dropped"),
        1.0
    );
}

#[test]
fn runs_repeat_bit_for_bit() {
    let text = scene(
        "gravity = [0.0, -9.81, 0.0]",
        &format!(
            "{}{}{}",
            grid("pins = [\"corners:row0\"]"),
            group("stretch", "", ""),
            group("bend", "", "compliance = 10.0")
        ),
    );
    let run = || {
        let mut s = sim(&text);
        for _ in 0..20 {
            s.step_frame().expect("step");
        }
        s.particles
            .x
            .iter()
            .flatten()
            .map(|c| c.to_bits())
            .collect::<Vec<_>>()
    };
    assert_eq!(run(), run());
}
