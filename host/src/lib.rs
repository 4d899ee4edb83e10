//! `riseg`: the host side of RISeg. It owns everything `riseg-core` leaves to the caller:
//! buffers (`Vec`-backed workspaces), file I/O, devices, the simulator and the CLI.

pub mod imageio;
pub mod workspace;
