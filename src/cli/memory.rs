//! What the machine can hold: the memory budget of a run (`--max-memory`,
//! else what the system says is available), and checks of work whose size
//! is known before it starts (pixel buffers, ray batches, scene copies),
//! so that a flag asking for too much is refused with how much it would
//! need, not by the allocator killing the process.

use std::sync::OnceLock;

use anyhow::{Result, bail};

/// The budget set by `--max-memory`, set once by `main`.
static MAX_MEMORY: OnceLock<Option<u64>> = OnceLock::new();

/// Sets the budget from `--max-memory` (`None`: what is available).
pub fn set_max_memory(bytes: Option<u64>) {
    let _ = MAX_MEMORY.set(bytes);
}

/// The memory a run may use: `--max-memory`, else the memory available
/// (Linux's `MemAvailable`), else unknown (`None`: nothing is refused).
pub fn budget() -> Option<u64> {
    MAX_MEMORY.get().copied().flatten().or_else(available)
}

/// The memory the system says is available for new work (Linux).
fn available() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

/// Refuses work that needs `need` bytes when the budget is smaller,
/// naming `what` asks for it and how to fix it.
pub fn check(need: u64, what: &str, fix: &str) -> Result<()> {
    if let Some(budget) = budget()
        && need > budget
    {
        bail!(
            "{what} would need about {} of memory, more than the {} this run may use \
             (--max-memory, else the memory available): {fix}",
            human(need),
            human(budget)
        );
    }
    Ok(())
}

/// A byte count for people: "3.2 GiB".
pub fn human(bytes: u64) -> String {
    let b = bytes as f64;
    let units = [("GiB", 30), ("MiB", 20), ("KiB", 10)];
    for (name, shift) in units {
        let unit = (1u64 << shift) as f64;
        if b >= unit {
            return format!("{:.1} {name}", b / unit);
        }
    }
    format!("{bytes} bytes")
}

/// Parses a size: bytes, or a number with K, M, G or T (powers of 1024;
/// an optional trailing "B" or "iB"), such as `512M` or `1.5G`.
pub fn parse_size(s: &str) -> Result<u64, String> {
    let t = s.trim();
    let t = t
        .strip_suffix("iB")
        .or_else(|| t.strip_suffix('B'))
        .unwrap_or(t);
    let (number, shift) = match t.chars().last() {
        Some(c @ ('K' | 'k' | 'M' | 'm' | 'G' | 'g' | 'T' | 't')) => {
            let shift = match c.to_ascii_uppercase() {
                'K' => 10,
                'M' => 20,
                'G' => 30,
                _ => 40,
            };
            (&t[..t.len() - 1], shift)
        }
        _ => (t, 0),
    };
    let x: f64 = number
        .trim()
        .parse()
        .map_err(|_| format!("{s:?} is not a size (bytes, or a number with K, M, G or T)"))?;
    let bytes = x * (1u64 << shift) as f64;
    if !(bytes.is_finite() && bytes >= 1.0 && bytes < u64::MAX as f64) {
        return Err(format!("{s:?} is not a size of at least one byte"));
    }
    Ok(bytes as u64)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse() {
        assert_eq!(parse_size("512M"), Ok(512 << 20));
        assert_eq!(parse_size("1.5G"), Ok(3 << 29));
        assert_eq!(parse_size("2GiB"), Ok(2 << 30));
        assert_eq!(parse_size("4096"), Ok(4096));
        assert!(parse_size("lots").is_err());
        assert!(parse_size("-1G").is_err());
        assert_eq!(human(3 << 29), "1.5 GiB");
    }
}
