//! A substep run stage by stage through the core's `predict_substep` and `run_stage` (the API
//! the benchmarks time single groups with) moves the particles exactly as `Simulation::substep`
//! does: the same prediction, the same contexts, the same order.

use nucleus_sdk::Stage;
use nucleus_tests::*;

/// Bits of every coordinate.
fn bits(sim: &nucleus_core::Simulation) -> Vec<[u64; 3]> {
    sim.positions()
        .iter()
        .map(|p| p.to_array().map(f64::to_bits))
        .collect()
}

#[test]
fn a_substep_run_stage_by_stage_gives_the_bits_of_a_whole_substep() {
    // One pass each (iterations 1, importance 1): the schedule is stretch (order 0), then
    // bend (order 1), each once.
    let text = drape_text(
        16,
        3,
        4,
        1,
        r#"
[[constraints]]
kind = "stretch"
objects = ["cloth"]
[[constraints]]
kind = "bend"
objects = ["cloth"]
params = { compliance = 1e-2 }
"#,
    );
    let (mut whole, mut staged) = (simulation(&text, &[]), simulation(&text, &[]));
    for sim in [&mut whole, &mut staged] {
        for _ in 0..2 {
            sim.step_frame().expect("step");
        }
    }
    assert_eq!(bits(&whole), bits(&staged));

    whole.substep(0).expect("substep");
    let group = |kind: &str| {
        staged
            .groups
            .iter()
            .position(|g| g.kind == kind)
            .unwrap_or_else(|| panic!("a {kind} group"))
    };
    let (stretch, bend) = (group("stretch"), group("bend"));
    let before = bits(&staged);
    staged.predict_substep(0).expect("prediction");
    assert_ne!(
        bits(&staged),
        before,
        "the prediction moves the free particles"
    );
    for g in [stretch, bend] {
        staged
            .run_stage(g, Stage::BeginSubstep, 0, 0)
            .expect("begin");
    }
    for g in [stretch, bend] {
        staged.run_stage(g, Stage::Project, 0, 0).expect("pass");
    }
    assert_eq!(bits(&staged), bits(&whole));
}
