//! Big arrays on 2 MiB pages where Linux offers them. A ray through a 10M-triangle mesh
//! reads tree nodes hundreds of megabytes apart: on 4 KiB pages nearly every such read
//! also misses the TLB and walks the page table, on 2 MiB pages far fewer do. And an
//! image written for the first time costs a page fault per page: 1,900 of them for an
//! 800×800 film on 4 KiB pages, a handful on 2 MiB ones. Linux hands out such transparent huge
//! pages to memory that asks for them (`madvise`, its default mode) before it is first
//! written; Embree asks for them the same way.

/// Arrays smaller than one huge page gain nothing.
const MIN_BYTES: usize = 2 << 20;

/// `v`, moved (if big enough) into fresh memory the kernel is asked to back with huge
/// pages. Same contents; only where they live changes.
pub fn on_huge_pages<T: Copy>(v: Vec<T>) -> Vec<T> {
    if std::mem::size_of_val(v.as_slice()) < MIN_BYTES {
        return v;
    }
    let mut out = with_capacity(v.len());
    out.extend_from_slice(&v);
    out
}

/// `n` zeros, on huge pages if that is big enough. Not written here: the memory comes
/// zeroed from the allocator (fresh pages from the kernel, for big arrays), so each page
/// is first touched, and faulted in, by whoever writes it first. A film is then faulted
/// in by the threads rendering it, in parallel, not by one thread before they start.
pub fn zeroed<T: bytemuck::Zeroable>(n: usize) -> Vec<T> {
    advised(bytemuck::allocation::zeroed_vec(n), n)
}

/// An empty vector with room for `n`, its memory advised for huge pages if it is big:
/// fill it without growing it past `n`, which would move it to memory not so advised.
pub fn with_capacity<T>(n: usize) -> Vec<T> {
    advised(Vec::with_capacity(n), n)
}

/// `v`, fresh and not yet written, with room for `n`: its memory advised for huge pages
/// if it is big enough.
fn advised<T>(v: Vec<T>, n: usize) -> Vec<T> {
    let bytes = n * std::mem::size_of::<T>();
    if bytes >= MIN_BYTES {
        advise_huge(v.as_ptr().cast::<u8>(), bytes);
    }
    v
}

/// Asks for huge pages for the whole pages inside `bytes` bytes from `start`. A hint:
/// if the kernel declines, nothing changes.
#[cfg(target_os = "linux")]
#[allow(unsafe_code)]
fn advise_huge(start: *const u8, bytes: usize) {
    // SAFETY: sysconf only reads a system constant.
    let page = unsafe { libc::sysconf(libc::_SC_PAGESIZE) };
    let page = if page > 0 { page as usize } else { return };
    let first = (start as usize).next_multiple_of(page);
    let end = (start as usize + bytes) / page * page;
    if end > first {
        // SAFETY: `first..end` lies inside an allocation this process owns (rounded
        // inwards to whole pages), and MADV_HUGEPAGE only changes how the kernel backs
        // those pages with memory: no mapping is added or removed and no byte's value
        // changes, so no Rust reference can observe it. Its result is ignored on purpose:
        // on failure the pages stay 4 KiB, as without the call.
        unsafe { libc::madvise(first as *mut libc::c_void, end - first, libc::MADV_HUGEPAGE) };
    }
}

#[cfg(not(target_os = "linux"))]
fn advise_huge(_: *const u8, _: usize) {}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn contents_survive_the_move_whatever_the_size() {
        for n in [0usize, 10, 3 << 20] {
            let v: Vec<u32> = (0..n as u32).map(|i| i.wrapping_mul(2654435761)).collect();
            assert_eq!(on_huge_pages(v.clone()), v);
            let z: Vec<u32> = zeroed(n);
            assert!(z.len() == n && z.iter().all(|&b| b == 0));
        }
    }
}
