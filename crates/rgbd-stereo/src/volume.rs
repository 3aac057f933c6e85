//! The cost-sum volume's allocation: zeroed, and backed by transparent huge pages where Linux
//! offers them on request (`madvise` mode), so its first touch costs ~60 faults of 2 MiB
//! instead of ~32 000 of 4 KiB at 960 x 540 x 128 (those serialise in the kernel and made the
//! first sweep slower on two threads than on one).

/// A zeroed buffer of `n` u16.
pub(crate) fn zeroed(n: usize) -> Vec<u16> {
    let v = vec![0u16; n];
    #[cfg(target_os = "linux")]
    advise_huge_pages(&v);
    v
}

#[cfg(target_os = "linux")]
fn advise_huge_pages(v: &[u16]) {
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
