//! The linear-algebra workspace checked before faer runs, so that a machine short of memory gets
//! an error instead of an abort.
//!
//! faer's x86 matrix products (the `private-gemm-x86` backend) give every thread that runs one a
//! packing buffer of twice the L3 size they detect, with an infallible allocation: when it
//! fails, the process aborts ("memory allocation of … bytes failed"). The size does not depend
//! on the problem: it follows the machine (L3 per core-share × the machine's cores; ~210 MiB on
//! the 2-core build VM, ~960 MiB on larger hosts), so even a 64 × 48 frame needs it. Before a
//! kernel that calls faer, [`reserve`] asks for that much memory for every thread that may run a
//! product and has no buffer yet (the rayon pool's workers the first time, the calling thread),
//! all at once and fallibly, gives it back, and at once has faer set up those threads' buffers
//! with one small product each: if the request fails the kernel returns
//! [`RgbdError::OutOfMemory`] and nothing aborts. The estimate is an upper bound of the
//! backend's (every CPU of `/sys`, not only the physical cores); without `/sys` no check is
//! made.

use std::cell::Cell;
use std::fs;
use std::path::Path;
use std::sync::OnceLock;

use faer::linalg::matmul::matmul;
use faer::{Accum, Mat, Par};
use rgbd_error::{Result, RgbdError};

thread_local! {
    /// This thread has run a faer product since [`reserve`] checked its buffer.
    static READY: Cell<bool> = const { Cell::new(false) };
}

/// The per-thread packing buffer of faer's x86 matrix product, as estimated from the cache
/// description under `cpu_root` (normally `/sys/devices/system/cpu`); `None` when it cannot be
/// read.
pub fn gemm_workspace_bytes(cpu_root: &Path) -> Option<u64> {
    let mut cpus = 0u64;
    let mut l1_share = 1u64;
    let mut l3_per_share = 0u64;
    for cpu in fs::read_dir(cpu_root).ok()?.flatten() {
        let name = cpu.file_name();
        let name = name.to_string_lossy();
        let is_cpu = name.len() > 3
            && name.starts_with("cpu")
            && name[3..].bytes().all(|b| b.is_ascii_digit());
        if !is_cpu {
            continue;
        }
        cpus += 1;
        let Ok(indices) = fs::read_dir(cpu.path().join("cache")) else {
            continue;
        };
        for index in indices.flatten() {
            let dir = index.path();
            let read = |f: &str| fs::read_to_string(dir.join(f)).map(|s| s.trim().to_owned());
            if !matches!(read("type").as_deref(), Ok("Data" | "Unified")) {
                continue;
            }
            let (Ok(level), Ok(size), Ok(shared)) =
                (read("level"), read("size"), read("shared_cpu_list"))
            else {
                continue;
            };
            let share = shared_count(&shared).max(1);
            match level.as_str() {
                "1" => l1_share = l1_share.max(share),
                "3" => l3_per_share = l3_per_share.max(parse_size(&size)? / share),
                _ => {}
            }
        }
    }
    if cpus == 0 || l3_per_share == 0 {
        return None;
    }
    Some(2 * l3_per_share * l1_share * cpus)
}

/// The CPUs of a `shared_cpu_list` such as `0-3,8,10-11`.
fn shared_count(list: &str) -> u64 {
    list.split(',')
        .filter(|s| !s.is_empty())
        .map(|item| match item.split_once('-') {
            Some((a, b)) => match (a.parse::<u64>(), b.parse::<u64>()) {
                (Ok(a), Ok(b)) if b >= a => b - a + 1,
                _ => 1,
            },
            None => 1,
        })
        .sum()
}

/// `size` as sysfs writes it: `48K`, `2048K`, `32M`, `1G` or bytes.
fn parse_size(size: &str) -> Option<u64> {
    let (digits, unit) = match size.as_bytes().last()? {
        b'K' => (&size[..size.len() - 1], 1u64 << 10),
        b'M' => (&size[..size.len() - 1], 1 << 20),
        b'G' => (&size[..size.len() - 1], 1 << 30),
        _ => (size, 1),
    };
    digits.parse::<u64>().ok()?.checked_mul(unit)
}

/// Asks for `threads` buffers of `bytes` at once, fallibly, and gives them back.
pub fn reserve_buffers(what: &'static str, bytes: u64, threads: usize) -> Result<()> {
    let out_of_memory = || RgbdError::OutOfMemory {
        what,
        bytes: bytes.saturating_mul(threads as u64),
        detail: format!(
            "the linear-algebra workspace: {} MiB for each of {threads} threads; free memory, \
             or run with fewer threads (RAYON_NUM_THREADS=1)",
            bytes.div_ceil(1 << 20)
        ),
    };
    let per = usize::try_from(bytes).map_err(|_| out_of_memory())?;
    let mut held: Vec<Vec<u8>> = Vec::with_capacity(threads);
    for _ in 0..threads {
        let mut buf = Vec::new();
        buf.try_reserve_exact(per).map_err(|_| out_of_memory())?;
        held.push(buf);
    }
    Ok(())
}

/// One product big enough for faer's x86 backend (above its 16³ small-product path), so that
/// the calling thread gets its packing buffer now; marks the thread ready.
fn warm() {
    if READY.with(Cell::get) {
        return;
    }
    let a = Mat::<f32>::from_fn(32, 32, |i, j| (i + j) as f32);
    let mut c = Mat::<f32>::zeros(32, 32);
    matmul(
        c.as_mut(),
        Accum::Replace,
        a.as_ref(),
        a.as_ref(),
        1.0,
        Par::Seq,
    );
    std::hint::black_box(&c);
    READY.with(|r| r.set(true));
}

/// Checks, before a kernel that runs faer's products, that every thread that may run one can
/// get its packing buffer (module docs); `what` names the kernel in the error.
pub fn reserve(what: &'static str) -> Result<()> {
    static BYTES: OnceLock<Option<u64>> = OnceLock::new();
    let Some(bytes) =
        *BYTES.get_or_init(|| gemm_workspace_bytes(Path::new("/sys/devices/system/cpu")))
    else {
        return Ok(());
    };
    let workers = rayon::broadcast(|_| !READY.with(Cell::get));
    let missing = workers.iter().filter(|&&m| m).count() + usize::from(!READY.with(Cell::get));
    if missing == 0 {
        return Ok(());
    }
    reserve_buffers(what, bytes, missing)?;
    rayon::broadcast(|_| warm());
    warm();
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fake_cpu(root: &Path, cpu: usize, caches: &[(&str, &str, &str, &str)]) {
        for (i, (kind, level, size, shared)) in caches.iter().enumerate() {
            let dir = root.join(format!("cpu{cpu}/cache/index{i}"));
            fs::create_dir_all(&dir).unwrap();
            for (f, v) in [("type", kind), ("level", level), ("size", size)] {
                fs::write(dir.join(f), format!("{v}\n")).unwrap();
            }
            fs::write(dir.join("shared_cpu_list"), format!("{shared}\n")).unwrap();
        }
    }

    #[test]
    fn estimate_follows_the_backend_rule() {
        let root = std::env::temp_dir().join(format!("rgbd-ws-{}", std::process::id()));
        let _ = fs::remove_dir_all(&root);
        // The build VM: 2 CPUs sharing a 105 MiB L3 -> 2 x 52.5 MiB x 1 x 2 CPUs = 210 MiB.
        for cpu in 0..2 {
            let caches = [
                ("Data", "1", "48K", "0"),
                ("Instruction", "1", "32K", "0"),
                ("Unified", "2", "2048K", "0"),
                ("Unified", "3", "107520K", "0-1"),
            ];
            fake_cpu(&root, cpu, &caches);
        }
        fs::create_dir_all(root.join("cpufreq")).unwrap(); // not a CPU
        assert_eq!(gemm_workspace_bytes(&root), Some(220_200_960));
        fs::remove_dir_all(&root).unwrap();
        assert_eq!(gemm_workspace_bytes(&root), None);
    }

    #[test]
    fn sizes_and_lists_parse() {
        assert_eq!(parse_size("48K"), Some(48 << 10));
        assert_eq!(parse_size("32M"), Some(32 << 20));
        assert_eq!(parse_size("1G"), Some(1 << 30));
        assert_eq!(parse_size("4096"), Some(4096));
        assert_eq!(parse_size("x"), None);
        assert_eq!(shared_count("0-3,8,10-11"), 7);
        assert_eq!(shared_count("5"), 1);
    }

    #[test]
    fn an_impossible_reservation_is_an_error_not_an_abort() {
        let err = reserve_buffers("oversegment", u64::MAX / 4, 3).unwrap_err();
        let msg = err.to_string();
        assert!(msg.starts_with("oversegment: out of memory"), "{msg}");
        assert!(msg.contains("RAYON_NUM_THREADS=1"), "{msg}");
        assert!(reserve_buffers("oversegment", 1 << 20, 3).is_ok());
    }

    #[test]
    fn reserve_readies_every_thread_once() {
        reserve("kmeans").unwrap();
        assert!(READY.with(Cell::get));
        assert!(rayon::broadcast(|_| READY.with(Cell::get))
            .iter()
            .all(|&r| r));
        reserve("kmeans").unwrap(); // nothing left to check
    }
}
