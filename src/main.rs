//! The `accelcal` binary: see `accelcal --help`.

use std::process::ExitCode;

/// The service's allocator: mimalloc, not the C library's. A submission
/// allocates a few hundred blocks on the runtime's workers, the blocking
/// pool and the SQLite writer (the parsed input, the result document, the
/// record, the audit entry), and frees many on another thread than the
/// one that allocated them; glibc's allocator took 14.5 % of the server's
/// CPU under the write benchmark, and with mimalloc a submission costs
/// 0.89 of the CPU it did (BENCHMARKS.md, "The allocator").
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

fn main() -> ExitCode {
    accelcal::cli::main()
}
