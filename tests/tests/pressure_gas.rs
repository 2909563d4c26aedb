//! The `gas` kind (an ideal gas in the mesh) through the dynamically loaded plugins.
//!
//! * **Boyle** (issue 6, test 5): a balloon with no pump and no leak is squeezed between two
//!   caps of its own vertices, pinned and driven toward each other by an animated OBJ
//!   sequence. Its volume (measured here from the positions) falls by over 20 %, and both the
//!   gas pressure the plugin reports and the pressure the solver actually pushes the membrane
//!   with follow `p₀V₀/V` within 2 %.
//! * **Pump** (test 6): pumping `Q` (Pa·m³/s) into a balloon whose membrane is slack (rest
//!   lengths longer than its edges, compression nearly free) inflates it at the predicted rate
//!   `dV/dt = Q/p_atm`: with no membrane tension the gas stays at ambient pressure, so
//!   `V(t) = (n₀ + Q t)/p_atm`.
//! * **Leak** (test 6): a taut balloon with a hole deflates, faster for lower air tightness,
//!   and the amount of gas falls at the rate the leak law gives from the reported pressure and
//!   opening area.

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
        assert!(
            reported < 0.02 && applied < 0.02,
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
