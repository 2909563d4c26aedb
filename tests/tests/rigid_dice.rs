//! `scenes/dice.toml`: three rigid dice (5 cm cubes of tets) thrown with a spin onto the ground
//! (restitution 0.4, friction 0.5 / 0.4), through the dynamically loaded `rigid` and
//! `collision` plugins. Each must tumble, come to rest, and lie flat on one of its faces on
//! the ground: the ground answers a die with the die's own mass (the collision's pushes,
//! answered by the rigid plugin), so it neither keeps bouncing nor balances on an edge, and
//! it never goes through the ground.

use nucleus_tests::*;

const DICE: [&str; 3] = ["red", "green", "blue"];
const SIZE: f64 = 0.05;
const THICKNESS: f64 = 0.002;

#[test]
fn thrown_dice_tumble_and_come_to_rest_flat_on_a_face() {
    let text = std::fs::read_to_string(shipped_scene("dice.toml")).unwrap();
    assert!(text.contains(&format!("thickness = {THICKNESS}")));
    let mut sim = simulation(&text, &[]);
    let start: Vec<_> = DICE
        .iter()
        .map(|d| sim.positions()[particles_of(&sim, d)].to_vec())
        .collect();
    let mut lowest = f64::INFINITY;
    let mut resting_since = [None; 3];
    let mut frame = 0;
    for _ in 0..180 {
        run(&mut sim, 1, |sim| {
            lowest = sim.positions().iter().map(|p| p.y).fold(lowest, f64::min);
        });
        frame += 1;
        for (k, d) in DICE.iter().enumerate() {
            let r = particles_of(&sim, d);
            let fastest = sim.velocities()[r]
                .iter()
                .map(|v| v.length())
                .fold(0.0, f64::max);
            if fastest > 1e-3 {
                resting_since[k] = None;
            } else if resting_since[k].is_none() {
                resting_since[k] = Some(frame);
            }
        }
    }
    // Never through the ground. The bodies move after the collision group's last pass (to
    // answer its pushes), and a die turning over an edge can end a substep a little into the
    // thickness with a corner the collision did not push (0.15 mm of the 2 mm; the next
    // substep pushes it out): at most a tenth of it.
    assert!(
        lowest > 0.9 * THICKNESS,
        "a particle went down to {lowest} m"
    );
    for (k, d) in DICE.iter().enumerate() {
        let r = particles_of(&sim, d);
        let x = &sim.positions()[r];
        // At rest for the last second at least (from frames 44-61 on).
        let since = resting_since[k].unwrap_or_else(|| panic!("{d} never comes to rest"));
        assert!(since <= 120, "{d} at rest only from frame {since}");
        // Flat on a face: its particles at exactly three heights — the face on the ground at
        // the thickness, the middle layer, the top face.
        for p in x {
            let layer = (p.y - THICKNESS) / (SIZE / 2.0);
            assert!(
                (layer - layer.round()).abs() * SIZE / 2.0 < 1e-5
                    && (0.0..=2.0).contains(&layer.round()),
                "{d} is not flat: a particle at {} m",
                p.y
            );
        }
        // It tumbled: some particle ends more than a die's size from where the throw's
        // translation alone would have carried it.
        let shift = (x.iter().copied().sum::<glam::DVec3>()
            - start[k].iter().copied().sum::<glam::DVec3>())
            / x.len() as f64;
        let turned = x
            .iter()
            .zip(&start[k])
            .map(|(p, q)| (*p - *q - shift).length())
            .fold(0.0, f64::max);
        assert!(turned > SIZE / 2.0, "{d} did not turn over ({turned} m)");
        eprintln!("{d}: at rest from frame {since}, turned {turned:.3} m, moved {shift}");
    }
}
