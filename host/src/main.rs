//! The `imunoise` command: parse, run, report. The command line lives in [`cli`], private
//! to this binary; every workflow it runs is in the `imunoise` library.

mod cli;

fn main() -> std::process::ExitCode {
    cli::main()
}
