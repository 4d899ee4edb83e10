#![doc = include_str!("../../README.md")]
//!
//! ## This crate
//!
//! `riseg` is the host side of RISeg. It owns everything `riseg-core` leaves to the caller:
//! buffers (`Vec`-backed workspaces), file I/O, devices, the simulator and the CLI.

pub mod eval;
pub mod metrics;
pub mod robot;
pub mod synthetic;
pub mod workspace;
