//! The `accelcal` binary: see `accelcal --help`.

use std::process::ExitCode;

fn main() -> ExitCode {
    accelcal::cli::main()
}
