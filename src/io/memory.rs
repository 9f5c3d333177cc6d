//! The memory budget checked before large allocations: a clear error naming what needed the
//! memory beats the operating system's out-of-memory kill.
//!
//! The budget is `POSEREG_MEMORY_LIMIT_MB` when set, else the memory the kernel says is
//! available (MemAvailable in /proc/meminfo); where neither is known nothing is checked.

/// Whether `needed` bytes fit the budget; the error says how much was needed and allowed.
pub fn check(needed: u64) -> Result<(), String> {
    match budget() {
        Some(allowed) if needed > allowed => Err(format!(
            "needs {} MB of memory but {} MB are available{}",
            needed >> 20,
            allowed >> 20,
            if std::env::var_os(LIMIT_VAR).is_some() {
                format!(" ({LIMIT_VAR})")
            } else {
                String::new()
            }
        )),
        _ => Ok(()),
    }
}

const LIMIT_VAR: &str = "POSEREG_MEMORY_LIMIT_MB";

fn budget() -> Option<u64> {
    if let Some(mb) = std::env::var(LIMIT_VAR)
        .ok()
        .and_then(|v| v.trim().parse::<u64>().ok())
    {
        return Some(mb << 20);
    }
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb << 10)
}
