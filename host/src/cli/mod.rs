//! The `riseg` subcommands, one module each, and what only commands use.

pub mod bench;
pub mod demo;
pub mod eval;
pub mod generate;
pub mod preview;
pub mod run;
