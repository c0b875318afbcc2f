//! Who holds a SQLite file this process cannot open: the process that has
//! it open under `unix-excl` ([`super::pool`]), found in `/proc/locks`.

use std::os::unix::fs::MetadataExt;
use std::path::Path;

use crate::store::StoreError;

/// The error for a file another process holds: names the file and, when
/// `/proc/locks` tells, the process; says what to do.
pub fn in_use(path: &Path) -> StoreError {
    let who = holder(path).map_or_else(
        || "another process".to_owned(),
        |(pid, name)| format!("process {pid} ({name})"),
    );
    StoreError::Unavailable(
        format!(
            "{} is in use by {who}: a SQLite file is served by one accelcal at a time — \
             stop that one first, or serve several replicas from PostgreSQL",
            path.display()
        )
        .into(),
    )
}

/// The process other than this one holding a POSIX lock on `path`, and its
/// command line.
fn holder(path: &Path) -> Option<(u32, String)> {
    let meta = std::fs::metadata(path).ok()?;
    let (dev, ino) = (meta.dev(), meta.ino());
    let locks = std::fs::read_to_string("/proc/locks").ok()?;
    let pid = locks.lines().find_map(|line| {
        let pid = locked_by(line, dev, ino)?;
        (pid != std::process::id()).then_some(pid)
    })?;
    let cmdline = std::fs::read(format!("/proc/{pid}/cmdline")).unwrap_or_default();
    let name = cmdline
        .split(|b| *b == 0)
        .filter(|a| !a.is_empty())
        .map(String::from_utf8_lossy)
        .collect::<Vec<_>>()
        .join(" ");
    Some((pid, if name.is_empty() { "?".into() } else { name }))
}

/// The pid of a `/proc/locks` line (`1: POSIX ADVISORY WRITE 4242
/// 08:01:1234 1073741824 1073742335`) when it locks inode `ino` of device
/// `dev` (major:minor in hex; Linux's `new_encode_dev` layout).
fn locked_by(line: &str, dev: u64, ino: u64) -> Option<u32> {
    let fields: Vec<&str> = line.split_whitespace().collect();
    let at = fields.iter().position(|f| f.matches(':').count() == 2)?;
    let pid: u32 = fields.get(at.checked_sub(1)?)?.parse().ok()?;
    let mut parts = fields[at].split(':');
    let major = u64::from_str_radix(parts.next()?, 16).ok()?;
    let minor = u64::from_str_radix(parts.next()?, 16).ok()?;
    let inode: u64 = parts.next()?.parse().ok()?;
    let same_dev = major == libc_major(dev) && minor == libc_minor(dev);
    (same_dev && inode == ino).then_some(pid)
}

/// glibc's `major()` of a `dev_t`.
fn libc_major(dev: u64) -> u64 {
    ((dev >> 32) & 0xffff_f000) | ((dev >> 8) & 0x0000_0fff)
}

/// glibc's `minor()` of a `dev_t`.
fn libc_minor(dev: u64) -> u64 {
    ((dev >> 12) & 0xffff_ff00) | (dev & 0x0000_00ff)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_lock_line_names_its_process_for_its_file_only() {
        // dev 0xfd01 is major 0xfd, minor 0x01.
        let line = "1: POSIX  ADVISORY  WRITE 4242 fd:01:1234 1073741824 1073742335";
        assert_eq!(locked_by(line, 0xfd01, 1234), Some(4242));
        assert_eq!(locked_by(line, 0xfd01, 1235), None);
        assert_eq!(locked_by(line, 0xfd02, 1234), None);
        let blocked = "1: -> POSIX  ADVISORY  WRITE 77 fd:01:1234 0 EOF";
        assert_eq!(locked_by(blocked, 0xfd01, 1234), Some(77));
        assert_eq!(locked_by("garbage", 0, 0), None);
    }
}
