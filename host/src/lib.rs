#![doc = include_str!("../../README.md")]
//!
//! ## This crate
//!
//! `riseg` is the host side of RISeg. It owns everything `riseg-core` leaves to the caller:
//! buffers (`Vec`-backed workspaces), file I/O, devices, the simulator and the CLI.
//!
//! - [`imageio`]: owned images, PNG and Middlebury `.flo` files, atomic writes.
//! - [`scene`]: the scene folder format (read and written).
//! - [`sim`]: the simulated tabletop (rapier3d physics, parry3d ray-cast RGB-D, exact
//!   ground truth).
//! - [`generate`]: simulated datasets in the scene folder format (`riseg gen`).
//! - [`preview`]: a picture of a scene for people.
//! - [`ceiling`]: the motion ceiling, the best mask motion could reveal, that RISeg is
//!   judged against.

pub mod bench;
pub mod camera;
pub mod ceiling;
pub mod demo;
pub mod draw;
pub mod episode;
pub mod eval;
pub mod flow;
pub mod generate;
pub mod imageio;
pub mod metrics;
pub mod preview;
pub mod replay;
pub mod robot;
pub mod scene;
pub mod segment;
pub mod sim;
pub mod synthetic;
pub mod tracker;
