//! The `gas` kind (an ideal gas in the mesh) through the dynamically loaded plugins.
//!
//! * **Boyle** (issue 6, test 5): a balloon with no pump and no leak is squeezed between two
//!   caps of its own vertices, pinned and driven toward each other by an animated OBJ
//!   sequence. Its volume (measured here from the positions) falls by over 20 %, and both the
//!   gas pressure the plugin reports and the pressure the solver actually pushes the membrane
//!   with follow `p₀V₀/V` to 1e-9 (the issue asks for 2 %).
//! * **Pump** (test 6): pumping `Q` (Pa·m³/s) into a balloon whose membrane is slack (rest
//!   lengths longer than its edges, compression nearly free) inflates it at the predicted rate
//!   `dV/dt = Q/p_atm`: with no membrane tension the gas stays at ambient pressure, so
//!   `V(t) = (n₀ + Q t)/p_atm`.
//! * **Leak** (test 6): a taut balloon with a hole deflates, faster for lower air tightness
//!   (an airtight one keeps all its gas), and the amount of gas falls at the rate the leak law
//!   gives from the reported pressure and opening area, within 1 %.

use nucleus_core::Simulation;
use nucleus_tests::*;

/// The enclosed volume of the object's triangles, `Σ a·(b × c) / 6` about its first vertex.
fn volume(sim: &Simulation, object: &str) -> f64 {
    let o = sim.object(object).expect("object");
    let x = sim.positions();
    let r = x[o.first as usize];
    o.triangles
        .iter()
        .map(|t| {
            let p = |k: usize| x[t[k] as usize] - r;
            p(0).dot(p(1).cross(p(2))) / 6.0
        })
        .sum()
}

fn stats(sim: &mut Simulation) -> impl Fn(&str) -> f64 {
    let reports = sim.reports().expect("reports");
    move |name: &str| {
        reports
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| *v)
            .unwrap_or_else(|| panic!("no stat {name} in {reports:?}"))
    }
}

fn obj_text(positions: &[[f64; 3]], triangles: &[[u32; 3]]) -> String {
    let mut text = String::new();
    for p in positions {
        text += &format!("v {} {} {}\n", p[0], p[1], p[2]);
    }
    for t in triangles {
        text += &format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1);
    }
    text
}

const RADIUS: f64 = 0.1;
/// Frames over which the caps close in, and the distance each moves.
const SQUEEZE_FRAMES: u32 = 60;
const SQUEEZE: f64 = 0.4 * RADIUS;

#[test]
fn squeezing_a_sealed_balloon_follows_boyle() {
    let sphere = nucleus_core::shapes::icosphere([0.0, 0.0, 0.0], RADIUS, 2);
    let cap = 0.85 * RADIUS;
    let dir = temp_dir("pressure-boyle");
    // Frame f: the top cap down and the bottom cap up by SQUEEZE f / SQUEEZE_FRAMES; the other
    // vertices are free, so their positions in the files do not matter.
    for f in 0..=SQUEEZE_FRAMES {
        let d = SQUEEZE * f as f64 / SQUEEZE_FRAMES as f64;
        let moved: Vec<[f64; 3]> = sphere
            .positions
            .iter()
            .map(|p| {
                let dy = if p[1] > cap {
                    -d
                } else if p[1] < -cap {
                    d
                } else {
                    0.0
                };
                [p[0], p[1] + dy, p[2]]
            })
            .collect();
        std::fs::write(
            dir.join(format!("squeeze_{f:04}.obj")),
            obj_text(&moved, &sphere.triangles),
        )
        .expect("write obj");
    }
    let (incompressibility, start) = (2000.0, 200.0);
    let text = format!(
        r#"
[solver]
frame_rate = 60.0
frames = 100
substeps = 10
gravity = [0.0, 0.0, 0.0]
damping = 2.0

[[objects]]
name = "balloon"
mass = 0.05
pins = [{{ min = [-1.0, {cap}, -1.0], max = [1.0, 1.0, 1.0] }}, {{ min = [-1.0, -1.0, -1.0], max = [1.0, -{cap}, 1.0] }}]
[objects.mesh]
path = "squeeze_0000.obj"
sequence = "squeeze_{{frame:04}}.obj"

[[constraints]]
kind = "stretch"
importance = 10
params = {{ compliance = 0.0, compression_compliance = 0.0 }}

[[constraints]]
kind = "gas"
params = {{ start_pressure = {start}, incompressibility = {incompressibility} }}
"#
    );
    // The scene lives beside its mesh files, which it names relative to itself.
    let scene = nucleus_core::Scene::parse(&text, &dir.join("boyle.toml"))
        .unwrap_or_else(|e| panic!("scene: {e}"));
    let mut sim = Simulation::build(&scene, &registry(&[plugin_dir()]))
        .unwrap_or_else(|e| panic!("build: {e}"));
    let pinned = sim.particles.inv_mass.iter().filter(|&&w| w == 0.0).count();
    assert!((2..40).contains(&pinned), "{pinned} pinned vertices");
    let v0 = volume(&sim, "balloon");
    let p0 = incompressibility + start;
    let s = stats(&mut sim);
    assert!((s("gas.pressure") - p0).abs() < 1e-9 * p0);
    let mut v_min = v0;
    let mut worst = (0.0_f64, 0.0_f64);
    for frame in 1..=100 {
        sim.step_frame().expect("step");
        let v = volume(&sim, "balloon");
        v_min = v_min.min(v);
        let boyle = p0 * v0 / v;
        let s = stats(&mut sim);
        let reported = (s("gas.pressure") / boyle - 1.0).abs();
        let applied = ((incompressibility + s("gas.applied_pressure")) / boyle - 1.0).abs();
        worst = (worst.0.max(reported), worst.1.max(applied));
        if frame % 20 == 0 {
            println!(
                "frame {frame}: V/V0 {:.4}, p0 V0/V {boyle:.1} Pa, reported {:.1} Pa, applied {:.1} Pa",
                v / v0,
                s("gas.pressure"),
                incompressibility + s("gas.applied_pressure")
            );
        }
        // The issue asks for 2 %: the gas is solved exactly along each correction's line and
        // warm-started, so the pressure pushing the membrane is Boyle's to rounding.
        assert!(
            reported < 1e-9 && applied < 1e-9,
            "frame {frame}: {reported}, {applied}"
        );
    }
    assert!(
        v_min < 0.8 * v0,
        "the squeeze must matter: V/V0 = {}",
        v_min / v0
    );
    println!(
        "smallest V/V0 {:.3}; worst relative pressure error: reported {:.2e}, applied {:.2e}",
        v_min / v0,
        worst.0,
        worst.1
    );
}

/// A gas balloon scene around an OBJ file, with the given stretch and gas parameters.
fn gas_balloon(path: &std::path::Path, stretch: &str, gas: &str) -> String {
    format!(
        r#"
[solver]
frame_rate = 60.0
substeps = 10
gravity = [0.0, 0.0, 0.0]
damping = 2.0

[[objects]]
name = "balloon"
mass = 0.05
[objects.mesh]
path = "{}"

[[constraints]]
kind = "stretch"
params = {stretch}

[[constraints]]
kind = "gas"
params = {gas}
"#,
        path.display()
    )
}

#[test]
fn pumping_a_slack_balloon_inflates_it_at_the_predicted_rate() {
    // Rest lengths 1.3 times the edges and nearly free compression: the membrane carries no
    // tension until the balloon has grown 1.3³ ≈ 2.2 times, so the gas stays at ambient
    // pressure and V = n / p_atm.
    let sphere = nucleus_core::shapes::icosphere([0.0, 0.0, 0.0], RADIUS, 2);
    let path = temp_dir("pressure-pump").join("balloon.obj");
    std::fs::write(&path, obj_text(&sphere.positions, &sphere.triangles)).expect("write obj");
    let ambient = 101_325.0;
    let mut sim = simulation(
        &gas_balloon(
            &path,
            "{ compliance = 0.0, compression_compliance = 1.0, rest_length_scale = 1.3 }",
            "{ pump_rate = 250.0 }",
        ),
        &[],
    );
    let v0 = volume(&sim, "balloon");
    let n0 = stats(&mut sim)("gas.amount");
    assert!((n0 - ambient * v0).abs() < 1e-9 * n0);
    let mut worst = 0.0_f64;
    let mut samples = Vec::new();
    for frame in 1..=60 {
        sim.step_frame().expect("step");
        let t = frame as f64 / 60.0;
        let n = stats(&mut sim)("gas.amount");
        assert!(
            (n - (n0 + 250.0 * t)).abs() < 1e-9 * n,
            "the pump adds exactly"
        );
        let v = volume(&sim, "balloon");
        let predicted = (n0 + 250.0 * t) / ambient;
        worst = worst.max((v / predicted - 1.0).abs());
        samples.push((t, v));
    }
    let (t1, v1) = samples[9];
    let (t2, v2) = samples[59];
    let rate = (v2 - v1) / (t2 - t1);
    let predicted = 250.0 / ambient;
    println!(
        "V/V0 {:.3} after 1 s; dV/dt {rate:.4e} m³/s vs Q/p_atm {predicted:.4e}; worst |V/V_pred - 1| {worst:.2e}",
        v2 / v0
    );
    assert!(v2 > 1.5 * v0, "the balloon must grow: {}", v2 / v0);
    assert!(
        (rate / predicted - 1.0).abs() < 0.01,
        "{rate} vs {predicted}"
    );
    assert!(worst < 0.005, "{worst}");
}

/// The icosphere without the triangles around vertex 0 (a pentagonal hole) and without
/// vertex 0 itself.
fn holed_sphere() -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
    let sphere = nucleus_core::shapes::icosphere([0.0, 0.0, 0.0], RADIUS, 2);
    let triangles: Vec<[u32; 3]> = sphere
        .triangles
        .iter()
        .filter(|t| !t.contains(&0))
        .map(|t| [t[0] - 1, t[1] - 1, t[2] - 1])
        .collect();
    (sphere.positions[1..].to_vec(), triangles)
}

#[test]
fn a_balloon_with_a_hole_deflates_faster_for_lower_air_tightness() {
    let (x, t) = holed_sphere();
    let path = temp_dir("pressure-leak").join("holed.obj");
    std::fs::write(&path, obj_text(&x, &t)).expect("write obj");
    let ambient = 101_325.0;
    let z = 413.0; // ρc of air, Pa·s/m
    let mut finals = Vec::new();
    for tightness in [1.0, 0.9, 0.5, 0.0] {
        // A taut membrane (rest lengths 0.8 of the edges) holding gas at 500 Pa.
        let mut sim = simulation(
            &gas_balloon(
                &path,
                "{ compliance = 1e-3, compression_compliance = 1e-3, rest_length_scale = 0.8 }",
                &format!("{{ start_pressure = 500.0, air_tightness = {tightness} }}"),
            ),
            &[],
        );
        let v0 = stats(&mut sim)("gas.volume");
        let mut prev = {
            let s = stats(&mut sim);
            (s("gas.amount"), s("gas.pressure"), s("gas.open_area"))
        };
        assert!(prev.2 > 1e-3, "the hole is open: {} m²", prev.2);
        // The leak law, dn/dt = −(1 − τ) A max(p, p_atm) (p − p_atm) / ρc, integrated by
        // the trapezoid rule over each substep from the reported states, against the gas
        // actually lost since the start.
        let rate = |(_, p, a): (f64, f64, f64)| {
            -(1.0 - tightness) * a * p.max(ambient) * (p - ambient) / z
        };
        // Measured from 0.1 s on, once the membrane has taken the gas's start pressure.
        let h = sim.h();
        let (mut n0, mut predicted, mut worst_law) = (prev.0, 0.0, 0.0_f64);
        for step in 1..=900 {
            sim.substep(step % 10).expect("substep");
            let s = stats(&mut sim);
            let now = (s("gas.amount"), s("gas.pressure"), s("gas.open_area"));
            if step <= 60 {
                n0 = now.0;
            } else {
                predicted += 0.5 * (rate(prev) + rate(now)) * h;
                if tightness == 1.0 {
                    assert_eq!(now.0, n0, "airtight: no gas lost");
                } else if step % 10 == 0 {
                    worst_law = worst_law.max(((now.0 - n0) / predicted - 1.0).abs());
                }
            }
            prev = now;
        }
        let v = stats(&mut sim)("gas.volume");
        println!(
            "air tightness {tightness}: V/V0 {:.3} after 1.5 s, gauge {:.1} Pa, worst leak-law error {worst_law:.2e}",
            v / v0,
            stats(&mut sim)("gas.gauge_pressure")
        );
        assert!(worst_law < 0.01, "tightness {tightness}: {worst_law}");
        finals.push((v / v0, prev.0));
    }
    // Lower tightness: less gas left, smaller balloon; every leaky one deflated well below
    // the airtight one.
    for w in finals.windows(2) {
        assert!(w[1].0 < w[0].0 && w[1].1 < w[0].1, "{finals:?}");
    }
    assert!(finals[1].0 < 0.95 * finals[0].0, "{finals:?}");
}
