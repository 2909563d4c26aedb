//! A rigid ball dropped on the ground with `restitution = 0`, through the dynamically loaded
//! `rigid` and `collision` plugins (the scene of `bench/rigid_drop.toml`: an icosphere of 162
//! particles, radius 0.11 m, 0.43 kg, its lowest point 0.885 m up). It should land dead.
//!
//! It does not with the kinds' default orders: the contact moves one particle of mass `M/N`
//! by the whole penetration, shape matching moves the body by about `1/N` of it, and the
//! penetration the body keeps comes back as velocity — a penalty spring that bounces the ball
//! 24–47 % of its drop, more at finer substeps (`docs/rigid_contacts.md`). That test is
//! ignored as a known failure, the acceptance test for a fix. With the rigid group ordered
//! after the collision group (the mitigation the rigid README gives) the ball lands almost
//! dead, and that is checked.

use glam::DVec3;
use nucleus_core::Simulation;
use nucleus_tests::*;

/// Height of the ball's centre resting on the ground: its radius plus the collision
/// thickness (m).
const REST: f64 = 0.11 + 0.005;

/// The bench's scene (`bench/rigid_drop.toml`, so the figures its README gives and these
/// checks are of one scene) at `substeps`; `rigid_order`: the rigid group's order (`None`:
/// the kind's default).
fn scene(substeps: u32, rigid_order: Option<i64>) -> String {
    let text = include_str!("../../bench/rigid_drop.toml");
    let rigid = "kind = \"rigid\"\nobjects = [\"ball\"]\n";
    assert!(text.contains("substeps = 10\n") && text.contains(rigid));
    let order = rigid_order.map_or(String::new(), |o| format!("order = {o}\n"));
    text.replace("substeps = 10\n", &format!("substeps = {substeps}\n"))
        .replace(rigid, &format!("{rigid}{order}"))
}

/// The ball's centre (its particles weigh the same).
fn centre(sim: &Simulation) -> DVec3 {
    let range = particles_of(sim, "ball");
    let n = range.len() as f64;
    sim.positions()[range].iter().copied().sum::<DVec3>() / n
}

/// Drops the ball and returns the rebound — how far above its rest height the centre rises
/// after it first stops falling, as a share of the drop — and the lowest the centre went (m).
fn rebound(substeps: u32, rigid_order: Option<i64>) -> (f64, f64) {
    let mut sim = simulation(&scene(substeps, rigid_order), &[]);
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
    assert!(
        landed,
        "{substeps} substeps: the ball never stopped falling"
    );
    ((apex - REST) / drop, lowest)
}

#[test]
fn a_rigid_ball_ordered_after_the_collisions_lands_almost_dead() {
    let mut worst: f64 = 0.0;
    for substeps in [10, 20, 40, 80] {
        let (share, lowest) = rebound(substeps, Some(200));
        eprintln!(
            "rigid after collision, {substeps} substeps: rebound {:.1} % of the drop, centre \
             down to {lowest:.4} m (rest {REST} m)",
            100.0 * share
        );
        worst = worst.max(share);
    }
    // Measured 2.1-4.1 % (2026-11-24); the default order gives 24-47 %.
    assert!(
        worst < 0.06,
        "the ball rebounds {:.1} % of its drop",
        100.0 * worst
    );
}

#[test]
#[ignore = "fails: rigid contacts are springy — a ball with restitution 0 rebounds 24-47 % of its drop at the default orders (docs/rigid_contacts.md)"]
fn a_rigid_ball_with_no_restitution_lands_dead() {
    for substeps in [10, 20, 40, 80] {
        let (share, lowest) = rebound(substeps, None);
        eprintln!(
            "default orders, {substeps} substeps: rebound {:.1} % of the drop, centre down to \
             {lowest:.4} m (rest {REST} m)",
            100.0 * share
        );
        assert!(
            share < 0.01,
            "{substeps} substeps: the ball rebounds {:.1} % of its drop",
            100.0 * share
        );
    }
}
