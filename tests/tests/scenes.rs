//! Every scene in `scenes/` builds through the dynamically loaded plugins and runs its first
//! frames with a finite state: a scene file never rots unnoticed. (What each scene shows is
//! tested by the plugin's own tests; this guards the files themselves.)

use nucleus_core::{Scene, Simulation};
use nucleus_tests::*;

#[test]
fn every_scene_builds_and_runs_its_first_frames() {
    let paths = shipped_scenes();
    assert!(paths.len() >= 16, "{} scenes", paths.len());
    let registry = registry(&[plugin_dir()]);
    for path in &paths {
        let name = path.display();
        let scene = Scene::load(path).unwrap_or_else(|e| panic!("{name}: {e}"));
        let mut sim =
            Simulation::build(&scene, &registry).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert!(!sim.groups.is_empty(), "{name}: no constraint group");
        for _ in 0..2 {
            sim.step_frame().unwrap_or_else(|e| panic!("{name}: {e}"));
        }
        assert!(
            sim.positions().iter().all(|p| p.is_finite()),
            "{name}: non-finite state"
        );
    }
}
