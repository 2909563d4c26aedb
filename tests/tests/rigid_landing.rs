//! A rigid ball dropped on the ground, through the dynamically loaded `rigid` and `collision`
//! plugins (the scene of `bench/rigid_drop.toml`: an icosphere of 162 particles, radius
//! 0.11 m, 0.43 kg, its lowest point 0.885 m up).
//!
//! With `restitution = 0` it must land dead, and with restitution `e` rebound to `e²` of its
//! drop, whatever the substeps and the groups' order. Before the collision plugin recorded its
//! pushes for the rigid plugin to answer with the body's mass, the contact moved one particle
//! of mass `M/N` by the whole penetration, shape matching moved the body by `1/N` of it, and
//! the penetration the body kept came back as velocity — a penalty spring that bounced the
//! ball 24–47 % of its drop at the default orders, more at finer substeps
//! (`docs/rigid_contacts.md`).

use glam::DVec3;
use nucleus_core::Simulation;
use nucleus_tests::*;

/// Height of the ball's centre resting on the ground: its radius plus the collision
/// thickness (m).
const REST: f64 = 0.11 + 0.005;

/// The bench's scene (`bench/rigid_drop.toml`, so the figures `plugins/rigid/README.md` gives
/// and these checks are of one scene) at `substeps`; `rigid_order`: the rigid group's order (`None`:
/// the kind's default); `restitution` the collision's.
fn scene(substeps: u32, rigid_order: Option<i64>, restitution: f64) -> String {
    let text = include_str!("../../bench/rigid_drop.toml");
    let rigid = "kind = \"rigid\"\nobjects = [\"ball\"]\n";
    let bounce = "restitution = 0.0,";
    assert!(text.contains("substeps = 10\n") && text.contains(rigid) && text.contains(bounce));
    let order = rigid_order.map_or(String::new(), |o| format!("order = {o}\n"));
    text.replace("substeps = 10\n", &format!("substeps = {substeps}\n"))
        .replace(rigid, &format!("{rigid}{order}"))
        .replace(bounce, &format!("restitution = {restitution:?},"))
}

/// The ball's centre (its particles weigh the same).
fn centre(sim: &Simulation) -> DVec3 {
    let range = particles_of(sim, "ball");
    let n = range.len() as f64;
    sim.positions()[range].iter().copied().sum::<DVec3>() / n
}

/// Drops the ball and returns the rebound — how far above its rest height the centre rises
/// after it first stops falling, as a share of the drop — and the lowest the centre went (m).
fn rebound(substeps: u32, rigid_order: Option<i64>, restitution: f64) -> (f64, f64) {
    let mut sim = simulation(&scene(substeps, rigid_order, restitution), &[]);
    let drop = centre(&sim).y - REST;
    let (mut lowest, mut apex, mut previous) = (f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY);
    let mut landed = false;
    run(&mut sim, 60, |sim| {
        let y = centre(sim).y;
        assert!(
            y.is_finite(),
            "{substeps} substeps: the ball's centre is {y}"
        );
        if !landed && y > previous {
            landed = true;
        }
        if landed {
            apex = apex.max(y);
        }
        lowest = lowest.min(y);
        previous = y;
    });
    if !landed {
        // A dead landing: the centre never rises again.
        apex = previous;
    }
    ((apex - REST) / drop, lowest)
}

#[test]
fn a_rigid_ball_with_no_restitution_lands_dead() {
    for order in [None, Some(200)] {
        for substeps in [10, 20, 40, 80] {
            let (share, lowest) = rebound(substeps, order, 0.0);
            eprintln!(
                "rigid order {order:?}, {substeps} substeps: rebound {:.3} % of the drop, centre \
                 down to {lowest:.4} m (rest {REST} m)",
                100.0 * share
            );
            // 0.0 % at every setting.
            assert!(
                share < 0.01,
                "rigid order {order:?}, {substeps} substeps: the ball rebounds {:.1} % of its drop",
                100.0 * share
            );
            // Into the ground by less than the collision thickness.
            assert!(
                lowest > REST - 0.005,
                "rigid order {order:?}, {substeps} substeps: the centre went down to {lowest} m"
            );
        }
    }
}

#[test]
fn a_rigid_ball_rebounds_to_the_square_of_its_restitution() {
    for e in [0.5, 0.8] {
        for substeps in [10, 40] {
            let (share, _) = rebound(substeps, None, e);
            eprintln!(
                "restitution {e}, {substeps} substeps: rebound {:.2} % of the drop",
                100.0 * share
            );
            // The centre leaves at `e` times its impact speed, so it climbs back `e²` of the
            // drop: 24.9-25.0 % and 63.9-64.0 %.
            assert!(
                (share - e * e).abs() < 0.01,
                "restitution {e}, {substeps} substeps: rebound {:.2} % of the drop, expected {:.0} %",
                100.0 * share,
                100.0 * e * e
            );
        }
    }
}

/// A scene of `frames` frames (60 a second, 10 substeps, gravity) with one rigid object,
/// `object` its `[[objects]]` table without the header, its rigid group's `rigid` lines added,
/// and a collision group (thickness 5 mm, no restitution, `collision` parameters added) with
/// the ground plane.
fn on_the_ground(frames: u32, object: &str, rigid: &str, collision: &str) -> String {
    let name = object
        .lines()
        .find_map(|l| l.strip_prefix("name = "))
        .expect("the object has a name");
    format!(
        r#"
[solver]
frame_rate = 60.0
frames = {frames}
substeps = 10
gravity = [0.0, -9.81, 0.0]
[[objects]]
{object}
[[constraints]]
kind = "rigid"
objects = [{name}]
{rigid}
[[constraints]]
kind = "collision"
params = {{ thickness = 0.005, restitution = 0.0, {collision}colliders = [
  {{ type = "plane", point = [0.0, 0.0, 0.0], normal = [0.0, 1.0, 0.0] }},
] }}
"#
    )
}

/// A 0.2 × 0.04 × 0.2 m slab of tets sliding flat on the ground at 2 m/s, dynamic friction
/// `μd = 0.4`; `rigid_order` as in [`scene`]. Returns its deceleration over frames 2–12 as a
/// multiple of Coulomb's `μd g`, and where it stopped (m).
fn slide(rigid_order: Option<i64>) -> (f64, f64) {
    let order = rigid_order.map_or(String::new(), |o| format!("order = {o}\n"));
    let text = on_the_ground(
        60,
        r#"name = "slab"
density = 500.0
velocity = [2.0, 0.0, 0.0]
[objects.tet_box]
min = [-0.1, 0.005, -0.1]
max = [0.1, 0.045, 0.1]
resolution = [2, 1, 2]"#,
        &order,
        "friction_static = 0.5, friction_dynamic = 0.4, ",
    );
    let mut sim = simulation(&text, &[]);
    let range = particles_of(&sim, "slab");
    let n = range.len() as f64;
    let mut xs = Vec::new();
    run(&mut sim, 60, |sim| {
        let c = sim.positions()[range.clone()]
            .iter()
            .copied()
            .sum::<DVec3>()
            / n;
        assert!(c.is_finite(), "the slab's centre is {c}");
        xs.push(c.x);
    });
    // `run` calls back after every substep, 10 a frame: the speed over frame `k`.
    let fps = 60.0;
    let speed = |k: usize| (xs[10 * k + 9] - xs[10 * k - 1]) * fps;
    let decel = (speed(2) - speed(12)) / (10.0 / fps);
    (decel / (0.4 * 9.81), *xs.last().unwrap())
}

#[test]
fn a_rigid_slab_sliding_on_the_ground_slows_at_coulombs_rate() {
    // Coulomb: it slows at μd g and stops after v²/(2 μd g) = 0.510 m (1.0000 μd g and
    // 0.508 m at both orders; 1.08 μd g if the friction's pushes were answered apart from the
    // normal ones).
    for order in [None, Some(200)] {
        let (decel, stop) = slide(order);
        eprintln!("rigid order {order:?}: slows at {decel:.4} μd g, stops at {stop:.4} m");
        assert!(
            (decel - 1.0).abs() < 0.01,
            "rigid order {order:?}: {decel} μd g"
        );
        assert!(
            (stop - 0.510).abs() < 0.01,
            "rigid order {order:?}: stops at {stop} m"
        );
    }
}

/// A 0.4 × 0.02 × 0.04 m lid of tets held by `pins` at its x = 0 end, 0.1 m above the
/// ground, falling about them onto the ground (`restitution = 0`): the lowest any particle is
/// after it first touched the ground, over the rest of 90 frames (m).
fn swing_down(pins: &str) -> f64 {
    let lid = format!(
        r#"name = "lid"
density = 700.0
pins = [{pins}]
[objects.tet_box]
min = [0.0, 0.1, -0.02]
max = [0.4, 0.12, 0.02]
resolution = [4, 1, 1]"#
    );
    let text = on_the_ground(90, &lid, "", "");
    let mut sim = simulation(&text, &[]);
    let (mut landed, mut highest) = (false, f64::NEG_INFINITY);
    run(&mut sim, 90, |sim| {
        let lowest = sim
            .positions()
            .iter()
            .map(|p| p.y)
            .fold(f64::INFINITY, f64::min);
        assert!(
            lowest.is_finite() && lowest > 0.0,
            "the lid went down to {lowest} m"
        );
        landed |= lowest <= 0.005 + 1e-6;
        if landed {
            highest = highest.max(lowest);
        }
    });
    assert!(landed, "the lid never reached the ground");
    highest
}

#[test]
fn a_hinged_lid_and_a_pivoted_bar_land_dead() {
    // Held along its x = 0 edge (a hinge, the pins on a line), then at one corner (a pivot).
    for (what, pins) in [
        (
            "hinged",
            "{ min = [-0.001, 0.099, -0.03], max = [0.001, 0.101, 0.03] }",
        ),
        (
            "pivoted",
            "{ min = [-0.001, 0.099, -0.021], max = [0.001, 0.101, -0.019] }",
        ),
    ] {
        let highest = swing_down(pins);
        eprintln!("{what}: after landing, its lowest particle rises to {highest:.4} m at most");
        // 0.0050 m (on the ground at its thickness) for both; 0.0265 and 0.0349 m (bouncing
        // back up) if pinned bodies did not answer the pushes.
        assert!(
            highest < 0.005 + 5e-4,
            "{what}: the lid bounces back up to {highest} m"
        );
    }
}
