//! The loop of Algorithm 1 and its seams, in the order one push runs through them:
//!
//! 1. [`camera`]: the [`Camera`](camera::Camera) trait and [`SceneReplay`](camera::SceneReplay)
//!    (a recorded scene played back); a [`CameraFrame`](camera::CameraFrame) is one RGB-D
//!    capture.
//! 2. [`tracker`]: static segmentation ([`crate::segment`]), optical flow ([`crate::flow`])
//!    and riseg-core's UpdateMask, frame after frame.
//! 3. [`episode`]: FindAction on the heatmap, depth and mask, then the robot: the loop.
//! 4. [`robot`]: [`plan_push`](robot::plan_push) maps FindAction's push into the robot
//!    frame and checks the arm's limits; the [`Robot`](robot::Robot) trait executes it.
//!
//! The simulator (`crate::sim`, feature `sim`) is one camera and one robot; the RealSense
//! (`realsense`, feature `realsense`) and the Franka Panda (`franka`, feature `franka`) are
//! the real ones; the loop never knows which. [`calib`] reads the hand-eye calibration a
//! real rig needs, and [`record`] records what a camera gives as a scene folder.

pub mod calib;
pub mod camera;
pub mod episode;
#[cfg(feature = "franka")]
pub mod franka;
#[cfg(feature = "realsense")]
pub mod realsense;
pub mod record;
pub mod robot;
pub mod tracker;
pub mod workspace;
