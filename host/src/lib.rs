//! `riseg`: the host side of RISeg. It owns everything `riseg-core` leaves to the caller:
//! buffers (`Vec`-backed workspaces), file I/O, devices, the simulator and the CLI.

pub mod flow;
pub mod synthetic;
pub mod workspace;
