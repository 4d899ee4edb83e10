//! The simulator as the loop's devices: [`SimCamera`] renders the scene, [`SimRobot`]
//! pushes in it. Both hold the same [`SimScene`], as a real camera and arm share one table.
//!
//! The robot frame is the simulator's world frame (table top at z = 0, z up), so the
//! hand-eye transform is the camera's true pose, [`SimScene::world_from_camera`]: not the
//! identity, since the camera is 0.6 m up and tilted.

use core::cell::RefCell;
use std::rc::Rc;

use super::{PUSHER_MAX_TRAVEL_M, SimScene, TABLE_HALF_EXTENTS_M};
use crate::{
    rig::camera::{Camera, CameraError, CameraFrame},
    rig::robot::{PushCommand, PushGeometry, PushLimits, Robot, RobotError, RobotSetup},
};

/// Longest push the simulated arm accepts, metres (approach included); its
/// [`PushLimits::max_push_len_m`].
pub const ARM_MAX_PUSH_LEN_M: f32 = 0.05;
/// Highest the simulated tool may go over the table, metres.
pub const ARM_MAX_TOOL_HEIGHT_M: f32 = 0.3;

/// Renders the shared scene, with its ground-truth labels and object poses.
#[derive(Debug)]
pub struct SimCamera {
    scene: Rc<RefCell<SimScene>>,
}

impl Camera for SimCamera {
    fn capture(&mut self) -> Result<CameraFrame, CameraError> {
        let frame = self.scene.borrow_mut().render();
        Ok(CameraFrame {
            rgb: frame.rgb,
            depth_m: frame.depth_m,
            intrinsics: frame.intrinsics,
            truth: Some(frame.labels),
            truth_poses: Some(frame.object_poses),
        })
    }
}

/// Pushes with the simulator's ball-shaped tool; refuses commands outside its limits.
#[derive(Debug)]
pub struct SimRobot {
    scene: Rc<RefCell<SimScene>>,
    limits: PushLimits,
    pushes: Vec<PushCommand>,
}

impl SimRobot {
    /// Replaces the limits (a tighter box, a shorter maximum).
    #[must_use]
    pub const fn with_limits(mut self, limits: PushLimits) -> Self {
        self.limits = limits;
        self
    }

    /// The commands executed so far, in order.
    #[must_use]
    pub fn pushes(&self) -> &[PushCommand] {
        &self.pushes
    }
}

impl Robot for SimRobot {
    fn limits(&self) -> PushLimits {
        self.limits
    }

    fn execute(&mut self, cmd: &PushCommand) -> Result<(), RobotError> {
        self.limits
            .check(cmd)
            .map_err(|e| RobotError(format!("refused: {e}")))?;
        self.scene
            .borrow_mut()
            .push(cmd)
            .map_err(|e| RobotError(e.to_string()))?;
        self.pushes.push(*cmd);
        Ok(())
    }
}

/// The simulated devices and their calibration; the loop
/// ([`crate::rig::episode::run_episode`]) uses them as it would a real camera and arm.
#[derive(Debug)]
pub struct SimRig {
    /// The camera.
    pub camera: SimCamera,
    /// The arm.
    pub robot: SimRobot,
    /// Hand-eye calibration (the camera's true pose in the world frame) and how the tool
    /// meets the objects.
    pub setup: RobotSetup,
}

impl SimRig {
    /// Devices over `scene`. The workspace box is the table top (x, y) from the tool's
    /// radius up to [`ARM_MAX_TOOL_HEIGHT_M`]; pushes up to [`ARM_MAX_PUSH_LEN_M`].
    #[must_use]
    pub fn new(scene: SimScene) -> Self {
        let radius_m = scene.config().pusher_radius_m;
        let robot_from_camera = scene.world_from_camera();
        let [hx, hy] = TABLE_HALF_EXTENTS_M;
        let limits = PushLimits {
            workspace_min_m: [-hx, -hy, radius_m],
            workspace_max_m: [hx, hy, ARM_MAX_TOOL_HEIGHT_M],
            max_push_len_m: ARM_MAX_PUSH_LEN_M.min(PUSHER_MAX_TRAVEL_M),
        };
        let geometry = PushGeometry {
            table_z_m: 0.0,
            approach_m: radius_m + 0.005,
            min_height_m: radius_m + 0.002,
        };
        let scene = Rc::new(RefCell::new(scene));
        Self {
            camera: SimCamera {
                scene: Rc::clone(&scene),
            },
            robot: SimRobot {
                scene,
                limits,
                pushes: Vec::new(),
            },
            setup: RobotSetup {
                robot_from_camera,
                geometry,
            },
        }
    }
}
