//! The `goniospec` command line: a thin layer that validates arguments and calls the
//! library (`src/cli/`, one file per command). Errors print with their whole cause chain;
//! exit codes are 0 (success), 1 (error, or defects found) and 2 (bad usage).

use std::process::ExitCode;

mod cli;

fn main() -> ExitCode {
    let cli = cli::Cli::parse_args();
    match cli::run(cli) {
        Ok(code) => code,
        // `goniospec reflectance f.gsa | head`: the reader has what it wanted. End quietly,
        // as ripgrep does (Rust ignores SIGPIPE, so the write returns BrokenPipe).
        Err(e) if cli::broken_pipe(&e) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            for cause in e.chain().skip(1) {
                eprintln!("  caused by: {cause}");
            }
            ExitCode::from(1)
        }
    }
}
