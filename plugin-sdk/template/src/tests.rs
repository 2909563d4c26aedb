//! The kind in whole scenes, in-process: the plugin is registered with `nucleus-core` exactly
//! as the host registers a loaded library, and scenes are built from TOML text. Each test
//! checks the simulation against the analytic behaviour stated in the [crate docs](crate).

use nucleus_core::{Registry, Simulation};
use nucleus_sdk::prelude::*;

use crate::{nucleus_plugin, KIND};

/// Builds a scene with this plugin registered in-process.
fn simulation(scene: &str) -> Result<Simulation, String> {
    let mut registry = Registry::default();
    registry.add_in_process(nucleus_plugin());
    Simulation::from_toml(scene, &registry).map_err(|e| e.to_string())
}

/// A scene of single particles `(name, position, vertex mass)`, gravity `g` (m/s², along −y),
/// and one group of this kind with `params` (TOML inline-table body).
fn scene(particles: &[(&str, [f64; 3], f64)], g: f64, extra: &str, params: &str) -> String {
    let mut s = format!(
        "[solver]\nframe_rate = 60.0\nsubsteps = 10\ngravity = [0.0, {}, 0.0]\n{extra}\n",
        -g
    );
    for (name, p, m) in particles {
        s.push_str(&format!(
            "[[objects]]\nname = \"{name}\"\nvertex_mass = {m:?}\n[objects.particles]\n\
             min = {p:?}\nmax = {p:?}\ncount = [1, 1, 1]\n"
        ));
    }
    s.push_str(&format!(
        "[[constraints]]\nkind = \"{KIND}\"\nparams = {{ {params} }}\n"
    ));
    s
}

fn run(sim: &mut Simulation, frames: u32) {
    for _ in 0..frames {
        sim.step_frame().unwrap_or_else(|e| panic!("{e}"));
    }
}

#[test]
fn a_released_particle_follows_implicit_euler_of_the_spring_exactly() {
    // Radius 0, no gravity: x_N = d (1 + h²/τ²)^(−N/2) cos(N atan(h/τ)) along the release
    // direction, for any mass.
    let (d, period) = (0.8, 0.5);
    for mass in [0.01, 3.0] {
        let mut sim = simulation(&scene(
            &[("p", [d, 0.0, 0.0], mass)],
            0.0,
            "",
            &format!("period = {period:?}"),
        ))
        .unwrap();
        let h = sim.h();
        let tau = period / std::f64::consts::TAU;
        for n in 1..=300u32 {
            sim.substep(n - 1).unwrap();
            let expected = d
                * (1.0 + h * h / (tau * tau)).powf(-0.5 * n as f64)
                * (n as f64 * (h / tau).atan()).cos();
            let x = sim.positions()[0];
            assert!(
                (x.x - expected).abs() < 1e-12 && x.y == 0.0 && x.z == 0.0,
                "mass {mass}, substep {n}: {x} vs {expected}"
            );
        }
    }
}

#[test]
fn the_swing_period_is_the_parameter() {
    // First return through the centre after a quarter period: t = T/4 within 1 %.
    let period = 0.4;
    let mut sim = simulation(&scene(
        &[("p", [0.5, 0.0, 0.0], 1.0)],
        0.0,
        "",
        &format!("period = {period:?}"),
    ))
    .unwrap();
    let h = sim.h();
    let mut n = 0u32;
    while sim.positions()[0].x > 0.0 {
        sim.substep(n % 10).unwrap();
        n += 1;
        assert!(n < 10_000, "never crossed the centre");
    }
    let t = n as f64 * h;
    assert!((t - period / 4.0).abs() < 0.01 * period, "{t} s");
}

#[test]
fn a_hanging_particle_settles_g_tau_squared_beyond_the_sphere_whatever_its_mass() {
    let (g, r, period) = (9.81, 0.3, 0.5);
    let tau = period / std::f64::consts::TAU;
    let mut sim = simulation(&scene(
        &[
            ("light", [0.0, 1.0, 0.0], 0.001),
            ("heavy", [0.5, 0.0, 0.2], 50.0),
        ],
        g,
        "damping = 5.0",
        &format!("center = [0.0, 2.0, 0.0], radius = {r:?}, period = {period:?}"),
    ))
    .unwrap();
    run(&mut sim, 600);
    let center = DVec3::new(0.0, 2.0, 0.0);
    for x in sim.positions() {
        let below = center - *x;
        assert!(
            (below.length() - (r + g * tau * tau)).abs() < 1e-9,
            "{} m from the centre",
            below.length()
        );
        assert!(
            below.x.abs() < 1e-9 && below.z.abs() < 1e-9,
            "straight below: {x}"
        );
    }
}

#[test]
fn a_hard_pull_keeps_particles_within_the_sphere_and_reports_it() {
    let mut sim = simulation(&scene(
        &[("a", [2.0, 0.0, 0.0], 1.0), ("b", [0.0, -3.0, 1.0], 0.2)],
        9.81,
        "",
        "radius = 0.5, period = 0.0",
    ))
    .unwrap();
    for frame in 0..30 {
        run(&mut sim, 1);
        for x in sim.positions() {
            assert!(x.length() <= 0.5 + 1e-12, "frame {frame}: {}", x.length());
        }
    }
    let residual = sim.residuals().unwrap()[0];
    assert_eq!(residual.count, 2);
    assert!(
        residual.max < 1e-12 && residual.energy == 0.0,
        "{residual:?}"
    );
    let reports = sim.reports().unwrap();
    let mean = sim.positions().iter().map(|x| x.length()).sum::<f64>() / 2.0;
    assert_eq!(reports.len(), 1);
    assert_eq!(reports[0].0, format!("{KIND}.mean_distance"));
    assert!((reports[0].1 - mean).abs() < 1e-15, "{reports:?} vs {mean}");
}

#[test]
fn particles_inside_the_free_ball_or_out_of_reach_fall_freely() {
    // One particle inside the ball, one beyond max_distance: both in free fall, bit for bit
    // as particles the group never pulls.
    let particles = [
        ("inside", [0.1, 0.0, 0.0], 1.0),
        ("far", [5.0, 0.0, 0.0], 1.0),
    ];
    let pulled = "radius = 3.0, max_distance = 4.0, period = 0.0";
    let mut free = simulation(&scene(&particles, 9.81, "", pulled)).unwrap();
    // The reference: both particles deep inside a huge free ball.
    let mut reference = simulation(&scene(&particles, 9.81, "", "radius = 100.0")).unwrap();
    run(&mut free, 10);
    run(&mut reference, 10);
    assert_eq!(free.positions(), reference.positions());
    assert!(free.positions()[0].y < -0.1, "it fell");
}

#[test]
fn the_result_does_not_depend_on_the_importance() {
    let cloud = "[[objects]]\nname = \"cloud\"\n[objects.particles]\nmin = [-1.0, 0.0, -1.0]\n\
                 max = [1.0, 2.0, 1.0]\ncount = [5, 5, 5]\n";
    let text = |importance: u32| {
        format!(
            "[solver]\nsubsteps = 4\n{cloud}[[constraints]]\nkind = \"{KIND}\"\n\
             importance = {importance}\nparams = {{ center = [0.0, 1.0, 0.0], radius = 0.4 }}\n"
        )
    };
    let mut one = simulation(&text(1)).unwrap();
    let mut four = simulation(&text(4)).unwrap();
    run(&mut one, 30);
    run(&mut four, 30);
    for (a, b) in one.positions().iter().zip(four.positions()) {
        assert!((*a - *b).length() < 1e-12, "{a} vs {b}");
    }
}

#[test]
fn kinematic_particles_are_left_out_and_never_moved() {
    let text = format!(
        "[[objects]]\nname = \"rope\"\npins = [\"start\"]\n[objects.rope]\nstart = [1.0, 0.0, 0.0]\n\
         end = [3.0, 0.0, 0.0]\nsegments = 4\n[[constraints]]\nkind = \"{KIND}\"\n\
         params = {{ period = 0.0 }}\n"
    );
    let mut sim = simulation(&text).unwrap();
    assert_eq!(sim.groups[0].len, 4, "5 vertices, 1 pinned");
    run(&mut sim, 2);
    assert_eq!(sim.positions()[0], DVec3::new(1.0, 0.0, 0.0));
    assert!(sim.positions()[1..].iter().all(|x| x.length() < 1e-12));
}

#[test]
fn the_factory_names_a_rejected_parameter() {
    let err = |params: &str| {
        simulation(&scene(&[("p", [1.0, 0.0, 0.0], 1.0)], 0.0, "", params))
            .err()
            .expect("must be refused")
    };
    let e = err("radius = 0.5, max_distance = 0.4");
    assert!(
        e.contains("`max_distance`") && e.contains("larger than radius"),
        "{e}"
    );
    let e = err("period = -1.0");
    assert!(
        e.contains("`period`") && e.contains("outside the valid range"),
        "{e}"
    );
    let e = err("perod = 1.0");
    assert!(e.contains("`perod`") && e.contains("period"), "{e}");
    let e = err("center = [0.0, 1.0]");
    assert!(e.contains("`center`"), "{e}");
}

#[test]
fn validate_checks_what_the_host_checks_for_in_process_callers() {
    let mut p = crate::AttractParams::default();
    assert!(p.validate().is_ok());
    p.radius = -1.0;
    assert_eq!(p.validate().unwrap_err().subject.as_str(), "radius");
    p.radius = 1.0;
    p.max_distance = 1.0;
    assert_eq!(p.validate().unwrap_err().subject.as_str(), "max_distance");
    p.max_distance = 1.5;
    assert!(p.validate().is_ok());
}
