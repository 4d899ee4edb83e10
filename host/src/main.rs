//! The `riseg` command line: everything is in [`riseg::cli`].

fn main() -> std::process::ExitCode {
    riseg::cli::main()
}
