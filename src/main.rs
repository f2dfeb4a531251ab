//! The `trazo` command.

fn main() -> std::process::ExitCode {
    trazo::cli::main()
}
