//! Golden frames of the collision scenes: each shipped scene with a `collision` group runs its
//! first frames through the loaded plugins, and the bits of every particle position after
//! every frame hash to the value stored in [`GOLDEN`]. A refactor of the collision plugin
//! must keep every one; a change of behaviour shows here as the scenes it changed.
//!
//! The frames are enough for each scene's contacts to happen: against a sphere and a plane
//! (`cloth_on_sphere`, `cloth_heap`), a capsule's features and a keyframed mesh paddle
//! (`collision_sweep`), two moving capsules (`rubber_band`), between objects (`bullet`,
//! `soccer_net`, `dice`), a bounce with restitution (`bouncing_ball`), and self-collision
//! (`cloth_twist`, which has no collider, so each of its contacts is a self-contact). Each
//! test checks that its scene made contacts, so a shortened scene still tests them.
//!
//! The hashes are of this platform's floating point (x86-64, the same on any thread count).

use nucleus_core::{Scene, Simulation};
use nucleus_tests::*;

/// A scene of `scenes/`, the frames it runs, and the hash of its positions after each.
struct Golden {
    scene: &'static str,
    frames: u32,
    hash: u64,
}

/// The stored hashes. After an intended change of behaviour, replace a scene's hash by the
/// one its failure prints (and say in the commit which scenes changed and why).
const GOLDEN: [Golden; 9] = [
    Golden {
        scene: "cloth_on_sphere",
        frames: 14,
        hash: 0x1a04_fdce_dcd5_56ef,
    },
    Golden {
        scene: "cloth_heap",
        frames: 10,
        hash: 0x0e78_ec20_39d2_340f,
    },
    Golden {
        scene: "cloth_twist",
        frames: 50,
        hash: 0x22c1_be41_7bab_22c1,
    },
    Golden {
        scene: "collision_sweep",
        frames: 48,
        hash: 0xccf4_1e5f_108a_0946,
    },
    Golden {
        scene: "bullet",
        frames: 12,
        hash: 0x0d39_d6d9_aad9_d2aa,
    },
    Golden {
        scene: "rubber_band",
        frames: 12,
        hash: 0x5b87_7775_4115_a292,
    },
    Golden {
        scene: "soccer_net",
        frames: 30,
        hash: 0x3812_1999_440e_b138,
    },
    Golden {
        scene: "bouncing_ball",
        frames: 60,
        hash: 0x81b3_08d8_1e15_5606,
    },
    Golden {
        scene: "dice",
        frames: 30,
        hash: 0xf424_1094_a74f_5f35,
    },
];

/// FNV-1a, 64 bits, over the bits of every coordinate.
fn fnv1a(hash: &mut u64, values: &[[f64; 3]]) {
    for b in values
        .iter()
        .flatten()
        .flat_map(|v| v.to_bits().to_le_bytes())
    {
        *hash ^= u64::from(b);
        *hash = hash.wrapping_mul(0x0000_0100_0000_01b3);
    }
}

/// Runs scene `name` for its [`GOLDEN`] frames and asserts the hash of its positions, and
/// that its collision group made contacts (the largest count in a substep, over the frames).
fn assert_golden(name: &str) {
    let golden = GOLDEN.iter().find(|g| g.scene == name).expect("listed");
    let registry = registry(&[plugin_dir()]);
    let path = shipped_scene(&format!("{name}.toml"));
    let scene = Scene::load(&path).unwrap_or_else(|e| panic!("{name}: {e}"));
    let mut sim = Simulation::build(&scene, &registry).unwrap_or_else(|e| panic!("{name}: {e}"));
    let mut hash = 0xcbf2_9ce4_8422_2325;
    let mut contacts = 0.0f64;
    for f in 0..golden.frames {
        sim.step_frame()
            .unwrap_or_else(|e| panic!("{name}, frame {f}: {e}"));
        fnv1a(&mut hash, &sim.particles.x);
        let reports = sim.reports().unwrap_or_else(|e| panic!("{name}: {e}"));
        let count = reports.iter().find(|(k, _)| k == "collision.contacts");
        contacts = contacts.max(count.expect("a collision report").1);
    }
    assert!(
        contacts > 0.0,
        "{name}: no contact in {} frames: the scene no longer tests the collisions",
        golden.frames
    );
    assert!(
        hash == golden.hash,
        "{name}: the positions of its first {} frames hash to {hash:#018x}, not {:#018x}: the \
         collision behaviour changed. If the change is intended, set `hash: {hash:#018x}` for \
         `{name}` in GOLDEN (tests/tests/collision_golden.rs) and name the changed scenes in \
         the commit; `cargo xtask scene-hashes --out FILE` before and after shows every shipped \
         scene that changed",
        golden.frames,
        golden.hash
    );
}

#[test]
fn cloth_on_sphere_keeps_its_golden_frames() {
    assert_golden("cloth_on_sphere");
}

#[test]
fn cloth_heap_keeps_its_golden_frames() {
    assert_golden("cloth_heap");
}

#[test]
fn cloth_twist_keeps_its_golden_frames() {
    assert_golden("cloth_twist");
}

#[test]
fn collision_sweep_keeps_its_golden_frames() {
    assert_golden("collision_sweep");
}

#[test]
fn bullet_keeps_its_golden_frames() {
    assert_golden("bullet");
}

#[test]
fn rubber_band_keeps_its_golden_frames() {
    assert_golden("rubber_band");
}

#[test]
fn soccer_net_keeps_its_golden_frames() {
    assert_golden("soccer_net");
}

#[test]
fn bouncing_ball_keeps_its_golden_frames() {
    assert_golden("bouncing_ball");
}

#[test]
fn dice_keeps_its_golden_frames() {
    assert_golden("dice");
}
