//! The cost-sum volume's allocation: left untouched until the first pass writes each row (so
//! a page's first touch is a write: one fault, no shared zero page to copy from and no TLB
//! shootdown), and backed by transparent huge pages where Linux offers them on request
//! (`madvise` mode), so its first touch costs ~60 faults of 2 MiB instead of ~32 000 of 4 KiB
//! at 960 x 540 x 128 (those serialise in the kernel and made the first sweep slower on two
//! threads than on one).

use std::mem::{ManuallyDrop, MaybeUninit};

use rgbd_error::{Result, RgbdError};

/// A buffer of `n` u16 not yet written (see the module docs), or
/// [`RgbdError::OutOfMemory`] when the allocator refuses it (a process under an address-space
/// limit, `ulimit -v`, aborted here: the volume is the matcher's one large buffer).
pub(crate) fn untouched(n: usize) -> Result<Vec<MaybeUninit<u16>>> {
    let mut v = Vec::new();
    v.try_reserve_exact(n).map_err(|_| RgbdError::OutOfMemory {
        what: "max_disparity",
        bytes: (n as u64).saturating_mul(2),
        detail: "the matcher's cost volume (2 bytes per pixel and disparity searched); free \
                     memory, or search fewer disparities or a smaller image"
            .to_string(),
    })?;
    // SAFETY: `MaybeUninit` needs no initialisation and the capacity is at least `n`.
    unsafe { v.set_len(n) };
    #[cfg(target_os = "linux")]
    advise_huge_pages(&v);
    Ok(v)
}

/// Zeroes `row` and returns it as initialised u16.
pub(crate) fn zero_row(row: &mut [MaybeUninit<u16>]) -> &mut [u16] {
    row.fill(MaybeUninit::new(0));
    // SAFETY: every element was just written; `MaybeUninit<u16>` has u16's layout.
    unsafe { std::slice::from_raw_parts_mut(row.as_mut_ptr().cast::<u16>(), row.len()) }
}

/// The buffer as u16.
///
/// # Safety
/// Every element of `v` must have been written (e.g. by [`zero_row`]).
pub(crate) unsafe fn assume_init(v: Vec<MaybeUninit<u16>>) -> Vec<u16> {
    let mut v = ManuallyDrop::new(v);
    // SAFETY: same allocation, length and capacity; `MaybeUninit<u16>` has u16's layout and
    // the caller guarantees every element is initialised.
    unsafe { Vec::from_raw_parts(v.as_mut_ptr().cast::<u16>(), v.len(), v.capacity()) }
}

#[cfg(target_os = "linux")]
fn advise_huge_pages<T>(v: &[T]) {
    const PAGE: usize = 4096;
    let start = v.as_ptr() as usize;
    let end = start + std::mem::size_of_val(v);
    let (lo, hi) = (start.div_ceil(PAGE) * PAGE, end / PAGE * PAGE);
    if hi > lo {
        // SAFETY: the range lies inside `v`'s allocation and MADV_HUGEPAGE changes only how
        // the pages are backed, never their contents. A refusal (no THP) is harmless.
        unsafe {
            libc::madvise(lo as *mut libc::c_void, hi - lo, libc::MADV_HUGEPAGE);
        }
    }
}
