//! What the whole-process benches share (`mod process;`): GNU time for
//! CPU time and peak memory, and the machine's load average to print
//! beside each figure.

use std::path::Path;
use std::process::{Command, Stdio};

/// `/usr/bin/time` when it is GNU time (accepts `-f`), else `None`.
pub fn gnu_time() -> Option<&'static Path> {
    let p = Path::new("/usr/bin/time");
    let ok = Command::new(p)
        .args(["-f", "%e", "true"])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    ok.then_some(p)
}

/// The 1, 5 and 15 minute load averages (`/proc/loadavg`), or "unknown".
pub fn load() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .map(|s| s.split_whitespace().take(3).collect::<Vec<_>>().join(" "))
        .unwrap_or_else(|_| "unknown".into())
}
