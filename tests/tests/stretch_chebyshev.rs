//! The Chebyshev option of the `stretch` kind through the loaded plugin: with several passes
//! per substep it lowers the strain of a hanging cloth, never moves a pin, and off (the
//! default) it changes nothing; too large a `ρ` is refused before the run.

use nucleus_core::Simulation;
use nucleus_tests::*;

/// The drape of `scenes/drape.toml` at `n × n`, `substeps` × `passes`, with `params` for the
/// stretch group.
fn drape(n: u32, frames: u32, substeps: u32, passes: u32, params: &str) -> Simulation {
    let constraints = format!("[[constraints]]\nkind = \"stretch\"\nparams = {{ {params} }}\n");
    simulation(&drape_text(n, frames, substeps, passes, &constraints), &[])
}

/// Mean over the last half of the frames of the stretch group's RMS strain, checking every
/// position stays finite and the pins stay put.
fn mean_rms_strain(mut sim: Simulation) -> f64 {
    let pins: Vec<usize> = (0..sim.particles.len())
        .filter(|&k| sim.particles.inv_mass[k] == 0.0)
        .collect();
    assert_eq!(pins.len(), 2);
    let pinned: Vec<_> = pins.iter().map(|&k| sim.positions()[k]).collect();
    mean_rms_residual(&mut sim, 0, |sim, f| {
        assert!(
            sim.positions().iter().all(|p| p.is_finite()),
            "frame {f}: not finite"
        );
        for (&k, &p) in pins.iter().zip(&pinned) {
            assert_eq!(sim.positions()[k], p, "pin {k} moved");
        }
    })
}

#[test]
fn with_several_passes_per_substep_chebyshev_lowers_the_strain() {
    let plain = mean_rms_strain(drape(24, 40, 10, 8, ""));
    let fast = mean_rms_strain(drape(24, 40, 10, 8, "chebyshev_rho = 0.9"));
    println!("24x24 drape, 10 substeps x 8 passes, mean RMS strain over the last 20 frames: plain {plain:.5}, chebyshev rho 0.9 {fast:.5}");
    assert!(fast < 0.8 * plain, "chebyshev {fast} vs plain {plain}");
}

#[test]
fn off_by_default_and_with_one_pass_it_changes_nothing() {
    let run = |params: &str, passes: u32| {
        let mut sim = drape(12, 10, 4, passes, params);
        for _ in 0..10 {
            sim.step_frame().expect("step");
        }
        sim.positions().to_vec()
    };
    assert_eq!(run("", 3), run("chebyshev_rho = 0.0", 3), "rho 0 is off");
    // The first pass of a substep is never accelerated (delay ≥ 1).
    assert_eq!(
        run("", 1),
        run("chebyshev_rho = 0.9, chebyshev_delay = 1", 1)
    );
    assert_ne!(
        run("", 3),
        run("chebyshev_rho = 0.9", 3),
        "and with 3 passes it acts"
    );
}

#[test]
fn a_spectral_radius_of_one_is_refused_naming_the_parameter() {
    let text = r#"
[[objects]]
name = "cloth"
[objects.grid]
size = [1.0, 1.0]
resolution = [4, 4]
[[constraints]]
kind = "stretch"
params = { chebyshev_rho = 1.0 }
"#;
    let err = Simulation::build(&scene(text), &registry(&[plugin_dir()]))
        .err()
        .expect("refused")
        .to_string();
    assert!(err.contains("chebyshev_rho"), "{err}");
}
