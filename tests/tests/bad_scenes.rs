//! Bad scenes get a clear error with `file:line:col`, a non-zero exit, and no output that
//! claims to be complete: malformed TOML, an unknown field, an unknown kind, a missing OBJ
//! file, a pin index out of range, NaN or negative mass, zero substeps, a substep length that
//! under- or overflows, a substep so long that gravity overflows in one, a schedule of billions
//! of calls a substep. With `--set` overrides an error in the file keeps its location in the
//! file, and one in an overridden value names the `--set` argument.

use std::path::{Path, PathBuf};

use nucleus_tests::*;

const GOOD: &str = r#"[solver]
frames = 3
substeps = 2

[[objects]]
name = "cloth"
mass = 1.0
pins = [0, 3]
[objects.grid]
size = [1.0, 1.0]
resolution = [4, 4]

[[constraints]]
kind = "stretch"
objects = ["cloth"]
"#;

/// Runs `nucleus run` on `text` written to a scene file; returns (exit code, last stderr line,
/// output directory).
fn run(tag: &str, text: &str) -> (Option<i32>, String, PathBuf, PathBuf) {
    run_with_sets(tag, text, &[])
}

fn assert_error_at(tag: &str, text: &str, line: usize, needle: &str) {
    let (code, msg, scene, out) = run(tag, text);
    assert_eq!(code, Some(2), "{tag}: exit code; stderr: {msg}");
    let loc = format!("error: {}:{line}:", scene.display());
    assert!(
        msg.starts_with(&loc),
        "{tag}: expected location {loc} in: {msg}"
    );
    assert!(msg.contains(needle), "{tag}: expected `{needle}` in: {msg}");
    assert!(!out.join("stats.csv").exists() && !out.join("run.json").exists());
    assert!(
        !out.exists(),
        "{tag}: a scene error must stop before any output is written"
    );
}

/// Runs `nucleus run` on `text` with the `--set` arguments `sets`; returns (exit code, last
/// stderr line, scene path, output directory).
fn run_with_sets(tag: &str, text: &str, sets: &[&str]) -> (Option<i32>, String, PathBuf, PathBuf) {
    let dir = temp_dir(tag);
    let scene = dir.join("scene.toml");
    std::fs::write(&scene, text).unwrap();
    let out = dir.join("out");
    let mut host = host_command("run", &scene, &out);
    for s in sets {
        host.args(["--set", s]);
    }
    let (code, last) = exit_and_last_error(&host.output().unwrap());
    (code, last, scene, out)
}

fn replace(from: &str, to: &str) -> String {
    assert!(GOOD.contains(from), "{from}");
    GOOD.replacen(from, to, 1)
}

#[test]
fn good_scene_runs_and_marks_output_complete() {
    let (code, msg, _, out) = run("good", GOOD);
    assert_eq!(code, Some(0), "{msg}");
    let stats = std::fs::read_to_string(out.join("stats.csv")).unwrap();
    assert_eq!(stats.lines().count(), 4, "header + 3 frames:\n{stats}");
    assert!(stats.starts_with("frame,time_s,wall_s,kinetic_j,potential_j,stretch.max,stretch.rms"));
    let run_json = std::fs::read_to_string(out.join("run.json")).unwrap();
    assert!(run_json.contains("\"complete\""));
    for f in 0..=3 {
        assert!(out.join(format!("frame_{f:04}.obj")).is_file());
    }
    assert!(!out.join("stats.csv.partial").exists());
}

#[test]
fn malformed_toml_is_located() {
    assert_error_at("malformed", &replace("frames = 3", "frames = = 3"), 2, "");
}

#[test]
fn unknown_field_is_located_and_named() {
    assert_error_at(
        "unknown-field",
        &replace("mass = 1.0", "mas = 1.0"),
        7,
        "unknown field `mas`",
    );
}

#[test]
fn unknown_parameter_is_located_and_named() {
    let text = replace(
        "objects = [\"cloth\"]\n",
        "objects = [\"cloth\"]\nparams = { complience = 0.0 }\n",
    );
    assert_error_at("unknown-param", &text, 16, "`complience`");
}

#[test]
fn a_nan_or_infinite_parameter_is_located_and_named() {
    // TOML has nan and inf; JSON, which carries parameters to plugins, has neither: they
    // arrived as `null` ("expected a number, found null").
    for (value, said) in [
        ("compliance = nan", "parameter `compliance` is NaN"),
        ("compliance = -inf", "parameter `compliance` is -inf"),
        ("extra = [1.0, inf]", "parameter `extra` is inf"),
    ] {
        let text = replace(
            "objects = [\"cloth\"]\n",
            &format!("objects = [\"cloth\"]\nparams = {{ {value} }}\n"),
        );
        assert_error_at("non-finite-param", &text, 16, said);
    }
}

#[test]
fn unknown_kind_is_located() {
    assert_error_at(
        "unknown-kind",
        &replace("kind = \"stretch\"", "kind = \"strech\""),
        14,
        "no plugin provides kind `strech`",
    );
}

#[test]
fn missing_obj_file_is_located_and_named() {
    let text = replace(
        "[objects.grid]\nsize = [1.0, 1.0]\nresolution = [4, 4]",
        "[objects.mesh]\npath = \"missing.obj\"",
    );
    let text = text.replace("pins = [0, 3]\n", "");
    assert_error_at("missing-obj", &text, 9, "missing.obj");
}

#[test]
fn pin_out_of_range_is_located() {
    assert_error_at(
        "pin-range",
        &replace("pins = [0, 3]", "pins = [0, 16]"),
        8,
        "pin index 16 is out of range",
    );
}

#[test]
fn nan_and_negative_mass_are_located() {
    assert_error_at(
        "nan-mass",
        &replace("mass = 1.0", "mass = nan"),
        7,
        "mass must be a positive finite number",
    );
    assert_error_at(
        "neg-mass",
        &replace("mass = 1.0", "mass = -2.0"),
        7,
        "mass must be a positive finite number",
    );
}

#[test]
fn bad_mass_maps_are_located() {
    assert_error_at(
        "mass-map-scale",
        &replace(
            "pins = [0, 3]\n",
            "pins = [0, 3]\nmass_maps = [{ vertices = [5], scale = 0.0 }]\n",
        ),
        9,
        "a mass map's scale must be a positive finite number",
    );
    assert_error_at(
        "mass-map-range",
        &replace(
            "pins = [0, 3]\n",
            "pins = [0, 3]\nmass_maps = [{ vertices = [16], scale = 2.0 }]\n",
        ),
        9,
        "mass map index 16 is out of range",
    );
}

#[test]
fn mass_maps_scale_the_selected_vertices_in_order() {
    let text = replace(
        "pins = [0, 3]\n",
        "pins = [0, 3]\nmass_maps = [{ vertices = [\"edge:rowN\"], scale = 1e-6 }, { vertices = [15, 5], scale = 3.0 }]\n",
    );
    let sim = simulation(&text, &[]);
    let m = &sim.particles.mass;
    let even = 1.0 / 16.0;
    for (i, &mi) in m.iter().enumerate() {
        let expected = match i {
            12..=14 => even * 1e-6,
            15 => even * 1e-6 * 3.0,
            5 => even * 3.0,
            _ => even,
        };
        assert!(
            (mi - expected).abs() <= 1e-15 * expected,
            "vertex {i}: {mi} vs {expected}"
        );
    }
    // Pinned vertices stay kinematic; the others' inverse masses follow their masses.
    let w = &sim.particles.inv_mass;
    assert_eq!((w[0], w[3]), (0.0, 0.0));
    assert!((w[12] * m[12] - 1.0).abs() < 1e-12);
}

#[test]
fn solid_density_needs_a_closed_surface() {
    assert_error_at(
        "solid-density-open",
        &replace("mass = 1.0", "solid_density = 500.0"),
        7,
        "solid_density: the surface is open",
    );
    assert_error_at(
        "solid-density-twice",
        &replace("mass = 1.0", "mass = 1.0\nsolid_density = 500.0"),
        6,
        "give only one of mass, density, vertex_mass, solid_density",
    );
}

#[test]
fn solid_density_gives_a_closed_surface_the_mass_of_the_solid_it_encloses() {
    let text = r#"
[[objects]]
name = "ball"
solid_density = 500.0
[objects.sphere]
center = [0.0, 0.0, 0.0]
radius = 0.11
subdivisions = 3
"#;
    let sim = simulation(text, &[]);
    let total: f64 = sim.particles.mass.iter().sum();
    // The icosphere's own volume is a little below the ball's (0.9 % at 3 subdivisions).
    let ball = 500.0 * 4.0 / 3.0 * std::f64::consts::PI * 0.11f64.powi(3);
    assert!(
        total < ball && total > 0.98 * ball,
        "{total} kg vs a ball's {ball} kg"
    );
    // Lumped by area: a regular-ish sphere's vertices weigh about the same.
    let (lo, hi) = sim
        .particles
        .mass
        .iter()
        .fold((f64::MAX, 0.0f64), |(l, h), &m| (l.min(m), h.max(m)));
    assert!(hi / lo < 2.0, "{lo} .. {hi}");
}

#[test]
fn zero_substeps_is_refused() {
    assert_error_at(
        "zero-substeps",
        &replace("substeps = 2", "substeps = 0"),
        3,
        "substeps must be at least 1",
    );
}

#[test]
fn a_substep_so_long_that_gravity_overflows_in_one_is_refused() {
    // h = 1 / (1e-300 × 2) ≈ 5e299 s: h² · 9.81 overflows. It was run, and the infinite
    // prediction blamed on the first plugin called.
    assert_error_at(
        "gravity-overflow",
        &replace("substeps = 2", "frame_rate = 1e-300\nsubsteps = 2"),
        3,
        "gravity's displacement over one substep, h²·|g| with h = 4.99",
    );
}

#[test]
fn a_substep_length_that_is_not_a_positive_finite_number_is_refused() {
    // 1 / (1e308 × 2) underflows to 0 s; 1 / (1e-310 × 2) overflows to infinity.
    for (rate, h) in [("1e308", "0e0 s"), ("1e-310", "inf s")] {
        assert_error_at(
            "substep-length",
            &replace(
                "substeps = 2",
                &format!("frame_rate = {rate}\nsubsteps = 2"),
            ),
            3,
            &format!("the substep length 1 / (frame_rate × substeps) = {h}"),
        );
    }
}

#[test]
fn a_schedule_of_billions_of_calls_a_substep_is_refused_before_it_is_laid_out() {
    // 4e9 iterations: the call list alone would need 96 GB, and the host aborted on the failed
    // allocation. The same through one constraint's importance.
    assert_error_at(
        "huge-iterations",
        &replace("substeps = 2", "substeps = 2\niterations = 4000000000"),
        4,
        "4000000000 projection calls per substep (iterations 4000000000",
    );
    assert_error_at(
        "huge-importance",
        &replace(
            "objects = [\"cloth\"]",
            "objects = [\"cloth\"]\nimportance = 4000000000",
        ),
        16,
        "more than the 1048576 the scheduler lays out",
    );
    // Up to the bound, the scene is built (and runs: one substep of it is a million calls of a
    // 16-particle cloth).
    let (code, msg, _, _) = run(
        "many-iterations",
        &replace("substeps = 2", "substeps = 2\niterations = 1048576")
            .replace("frames = 3", "frames = 1"),
    );
    assert_eq!(code, Some(0), "{msg}");
}

#[test]
fn unknown_object_in_constraint_is_located() {
    assert_error_at(
        "unknown-object",
        &replace("objects = [\"cloth\"]", "objects = [\"clot\"]"),
        15,
        "no object named `clot`",
    );
}

#[test]
fn obj_mesh_loads_relative_to_the_scene() {
    let dir = temp_dir("obj-mesh");
    std::fs::write(
        dir.join("tri.obj"),
        "v 0 0 0\nv 1 0 0\nv 0 0 1\nv 1 0 1\nf 1 2 3\nf 2 4 3\n",
    )
    .unwrap();
    let text = replace(
        "[objects.grid]\nsize = [1.0, 1.0]\nresolution = [4, 4]",
        "[objects.mesh]\npath = \"tri.obj\"",
    )
    .replace("pins = [0, 3]", "pins = [0]");
    let scene_path = dir.join("scene.toml");
    std::fs::write(&scene_path, &text).unwrap();
    let scene = nucleus_core::Scene::load(Path::new(&scene_path)).unwrap();
    let sim = nucleus_core::Simulation::build(&scene, &registry(&[plugin_dir()])).unwrap();
    assert_eq!(sim.particles.len(), 4);
    assert_eq!(
        sim.groups[0].len, 5,
        "two triangles share one edge: 5 edges"
    );
}

/// An error in a value a `--set` wrote names that argument, not a line of the file: the line
/// would be in a text the user never sees (before, `--set` gave locations in the re-serialised
/// scene, such as line 2 of a file whose line 2 is a comment).
#[test]
fn an_error_in_an_overridden_value_names_the_set_argument() {
    for (set, needle) in [
        (
            "constraints.0.params = { compliance = -1.0 }",
            "parameter `compliance`",
        ),
        ("solver.substeps=0", "substeps must be at least 1"),
        ("constraints.0.importance=-1", "invalid value"),
        ("objects.0.pins=[0, 99]", "pin index 99 is out of range"),
        (
            "constraints.0.kind=\"strech\"",
            "no plugin provides kind `strech`",
        ),
        ("constraints.3.importance=2", "index 3 out of range"),
    ] {
        let (code, msg, scene, out) = run_with_sets("set-error", GOOD, &[set]);
        assert_eq!(code, Some(2), "{set}: exit code; stderr: {msg}");
        let named = [
            format!("error: {}: --set {set}: ", scene.display()),
            format!("error: {} (--set {set}): ", scene.display()),
        ];
        assert!(
            named.iter().any(|n| msg.starts_with(n.as_str())),
            "{set}: expected the argument named in: {msg}"
        );
        assert!(msg.contains(needle), "{set}: expected `{needle}` in: {msg}");
        assert!(!out.exists(), "{set}: no output may be written");
    }
}

/// An error in the file keeps its line and column with overrides that replace values and
/// insert keys above it (the overrides are made in the file's text, not by re-writing it).
#[test]
fn an_error_in_the_file_keeps_its_location_under_overrides() {
    let text = format!(
        "{GOOD}\n[[constraints]]\nkind = \"stretch\"\nobjects = [\"cloth\"]\nparams = {{ bogus = 1 }}\n"
    );
    let line = text.lines().position(|l| l.contains("bogus")).unwrap() + 1;
    for sets in [
        &[][..],
        &["solver.substeps=3"][..],
        &[
            "constraints.0.importance=2",
            "solver.iterations=2",
            "objects.0.mass=2.0",
        ][..],
    ] {
        let (code, msg, scene, _) = run_with_sets("file-error-set", &text, sets);
        assert_eq!(code, Some(2), "{sets:?}: exit code; stderr: {msg}");
        let loc = format!("error: {}:{line}:", scene.display());
        assert!(msg.starts_with(&loc), "{sets:?}: expected {loc} in: {msg}");
        assert!(msg.contains("parameter `bogus`"), "{sets:?}: {msg}");
    }
}

/// Overrides reach keys of inline tables, entries of arrays and of arrays of tables, and
/// insert missing keys; the scene runs with what they set.
#[test]
fn overrides_set_inline_table_keys_array_entries_and_new_keys() {
    let text = replace(
        "kind = \"stretch\"",
        "kind = \"stretch\"\nparams = { compliance = 0.0 }",
    );
    // A key inside the inline table is reached (and its bad value named).
    let (code, msg, _, _) = run_with_sets(
        "set-inline",
        &text,
        &["constraints.0.params.compliance=-1.0"],
    );
    assert_eq!(code, Some(2), "stderr: {msg}");
    assert!(
        msg.contains("--set constraints.0.params.compliance=-1.0") && msg.contains("`compliance`"),
        "{msg}"
    );
    let (code, msg, _, out) = run_with_sets(
        "set-ok",
        &text,
        &[
            "constraints.0.params.compliance=1e-6",
            "objects.0.pins.1=2",
            "constraints.0.importance=2",
            "solver.frames=2",
        ],
    );
    assert_eq!(code, Some(0), "stderr: {msg}");
    let run = std::fs::read_to_string(out.join("run.json")).unwrap();
    assert!(
        run.contains("\"frames\":2"),
        "the file's 3 frames were not overridden: {run}"
    );
    // Pins 0 and 2 (the override) hold their rest positions on the 4 x 4 grid's first row,
    // 1 and 3 (the file's second pin) fall.
    let obj = std::fs::read_to_string(out.join("frame_0001.obj")).unwrap();
    let v: Vec<[f64; 3]> = obj
        .lines()
        .filter_map(|l| l.strip_prefix("v "))
        .map(|l| {
            let c: Vec<f64> = l.split_whitespace().map(|c| c.parse().unwrap()).collect();
            [c[0], c[1], c[2]]
        })
        .collect();
    let rest = |i: usize| [i as f64 / 3.0, 0.0, 0.0];
    for i in [0, 2] {
        for c in 0..3 {
            assert!(
                (v[i][c] - rest(i)[c]).abs() < 1e-12,
                "pin {i} moved: {:?}",
                v[i]
            );
        }
    }
    for i in [1, 3] {
        assert!(v[i][1] < -1e-4, "particle {i} did not fall: {:?}", v[i]);
    }
}

/// An output directory that cannot be made (here: under a file) is bad input, exit 2, with
/// the path named; the file is left as it was.
#[test]
fn an_output_directory_that_cannot_be_made_is_refused_as_bad_input() {
    let dir = temp_dir("bad-out");
    let scene = dir.join("scene.toml");
    std::fs::write(&scene, GOOD).unwrap();
    let blocker = dir.join("a_file");
    std::fs::write(&blocker, "keep me").unwrap();
    let out = blocker.join("out");
    let res = host_command("run", &scene, &out).output().unwrap();
    let (code, msg) = exit_and_last_error(&res);
    assert_eq!(code, Some(2), "stderr: {msg}");
    assert!(
        msg.contains(&out.display().to_string())
            && msg.contains("cannot create the output directory"),
        "{msg}"
    );
    assert_eq!(std::fs::read_to_string(&blocker).unwrap(), "keep me");
}

/// An empty scene file is a valid scene (every field has a default) and runs, but the host
/// warns that it has no objects, naming the file.
#[test]
fn an_empty_scene_runs_with_a_warning_that_it_has_no_objects() {
    let (code, msg, scene, out) = run("empty", "");
    assert_eq!(code, Some(0), "stderr: {msg}");
    assert!(
        msg.contains("warning:")
            && msg.contains(&scene.display().to_string())
            && msg.contains("no objects"),
        "{msg}"
    );
    assert!(out.join("run.json").exists());
}
