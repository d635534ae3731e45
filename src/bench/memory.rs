//! Peak memory of a benchmark case: the device allocation the context counts
//! ([`crate::GpuContext::peak_allocated_bytes`]) and the process's peak
//! resident set (Linux `VmHWM`, reset through `/proc/self/clear_refs`). On
//! lavapipe the device's buffers are host memory, so the resident peak holds
//! both the device allocation and the host's copies of the image.

/// Restarts the process's peak resident set from its current size (Linux;
/// nothing elsewhere).
pub fn reset_peak_rss() {
    let _ = std::fs::write("/proc/self/clear_refs", "5");
}

/// The process's peak resident set in bytes since the last
/// [`reset_peak_rss`] (`VmHWM`), or `None` where `/proc` does not tell.
pub fn peak_rss_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_peak_sees_a_big_allocation_and_resets() {
        let Some(_) = super::peak_rss_bytes() else {
            return; // not Linux
        };
        super::reset_peak_rss();
        let before = super::peak_rss_bytes().unwrap();
        let v = vec![1u8; 64 << 20];
        std::hint::black_box(&v);
        let during = super::peak_rss_bytes().unwrap();
        assert!(during >= before + (60 << 20), "{before} -> {during}");
        drop(v);
        super::reset_peak_rss();
        let after = super::peak_rss_bytes().unwrap();
        assert!(after + (32 << 20) < during, "reset: {during} -> {after}");
    }
}
