//! The scene folder's JSON readers in `riseg::io::scene`: `scene_camera.json`
//! (`SceneCamera::from_json`), `actions.json` (`actions_from_json`) and `poses.json`
//! (`poses_from_json`), each on the same arbitrary bytes. The first byte gives the scene's
//! push count (`byte % 4`; frames = pushes + 1), the rest is the file.
//!
//! Contract checked: no panic; an accepted camera has a non-empty size, finite values and
//! positive focal lengths and depth unit, and an accepted camera or action list written
//! back as JSON reads back equal; accepted poses hold one list per frame with labels from
//! 1 and unit quaternions.

#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;
use riseg::io::scene::{SceneCamera, actions_from_json, poses_from_json};

fuzz_target!(|data: &[u8]| {
    let Some((&count, json)) = data.split_first() else {
        return;
    };
    let pushes = usize::from(count % 4);
    let path = Path::new("fuzz.json");
    if let Ok(camera) = SceneCamera::from_json(path, json) {
        assert!(camera.width > 0 && camera.height > 0, "{camera:?}");
        let values = [
            camera.fx,
            camera.fy,
            camera.cx,
            camera.cy,
            camera.depth_unit_m,
        ];
        assert!(values.iter().all(|v| v.is_finite()), "{camera:?}");
        assert!(camera.fx > 0.0 && camera.fy > 0.0 && camera.depth_unit_m > 0.0);
        let text = serde_json::to_vec(&camera).expect("serialise a camera");
        let back = SceneCamera::from_json(path, &text).expect("read back a written camera");
        assert!(
            back == camera,
            "camera JSON round trip: {camera:?} -> {back:?}"
        );
    }
    if let Ok(actions) = actions_from_json(path, json, pushes) {
        assert!(actions.len() == pushes);
        let text = serde_json::to_vec(&actions).expect("serialise actions");
        let back = actions_from_json(path, &text, pushes).expect("read back written actions");
        assert!(
            back == actions,
            "actions JSON round trip: {actions:?} -> {back:?}"
        );
    }
    if let Ok(poses) = poses_from_json(path, json, pushes + 1) {
        assert!(poses.len() == pushes + 1);
        for pose in poses.iter().flatten() {
            assert!(pose.label >= 1);
            assert!((pose.world_from_object.rotation.norm() - 1.0).abs() < 1e-5);
        }
    }
});
