//! The `imunoise` command: parse, run, report. All work is in the library (`imunoise::cli`).

fn main() -> std::process::ExitCode {
    imunoise::cli::main()
}
