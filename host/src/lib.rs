#![doc = include_str!("../../README.md")]
//!
//! ## This crate
//!
//! `riseg` is the host side of RISeg. It owns everything `riseg-core` leaves to the caller:
//! devices, file I/O, the simulator, the built-in segmenter and optical flow, scoring and
//! the CLI. Modules by role, each importing only the ones below it:
//!
//! - `cli` (feature `cli`): the `riseg` subcommands (`demo`, `bench`, `gen`, `run`, `eval`, ...).
//! - `sim` (feature `sim`): the simulated tabletop (rapier3d physics, parry3d ray-cast RGB-D, exact
//!   ground truth): one camera and one robot for the loop.
//! - [`rig`]: the loop of Algorithm 1 and its seams: camera, tracker, episode, robot.
//! - [`segment`]: the built-in static segmenter (labels + FindAction's heatmap).
//! - [`flow`]: the built-in dense optical flow (DIS).
//! - `onnx` (feature `onnx`): a learned segmenter and flow from ONNX files.
//! - [`io`]: owned images, PNG and `.flo` files, atomic writes, the scene folder format.
//! - [`draw`]: colours and drawing for pictures.
//! - [`eval`]: UOIS metrics and the motion ceiling.
//! - [`testkit`]: synthetic inputs for tests, benches and examples.
//!
//! ## Features
//!
//! - `cli` (default): the `riseg` binary and the `cli` module (clap, indicatif, anyhow);
//!   implies `sim`.
//! - `sim` (default): the simulator, the `sim` module (rapier3d, parry3d); implies `threads`.
//! - `threads` (default): rayon in the optical flow and the renderer.
//! - `onnx` (off): `onnx::OnnxSegmenter` and `onnx::OnnxFlow`, and `--segmenter` /
//!   `--flow PATH.onnx` on the CLI, through ONNX Runtime (`ort`), loaded at run time from
//!   `ORT_DYLIB_PATH` or the `onnxruntime` Python wheel.
//! - `realsense`: the Intel RealSense D415 camera, `rig::realsense` (librealsense2 loaded at
//!   run time with `libloading`; the only `unsafe` in riseg, confined to its FFI module).
//! - `franka`: the Franka Emika Panda robot, `rig::franka` (an own FCI client, no
//!   dependency).
//!
//! `--no-default-features` leaves the pure parts (flow, segment, eval, io, rig, testkit),
//! which build for `wasm32-unknown-unknown` and compute the same on every target
//! (transcendentals through `libm`).

#[cfg(feature = "cli")]
pub mod cli;
pub mod draw;
pub mod eval;
pub mod flow;
pub mod io;
#[cfg(feature = "onnx")]
pub mod onnx;
mod par;
pub mod rig;
pub mod segment;
#[cfg(feature = "sim")]
pub mod sim;
pub mod testkit;
