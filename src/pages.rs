//! Big arrays on 2 MiB pages where Linux offers them. A ray through a 10M-triangle mesh
//! reads tree nodes hundreds of megabytes apart: on 4 KiB pages nearly every such read
//! also misses the TLB and walks the page table, on 2 MiB pages far fewer do. And an
//! image written for the first time costs a page fault per page: 1,900 of them for an
//! 800×800 film on 4 KiB pages, a handful on 2 MiB ones. Linux hands out such transparent huge
//! pages to memory that asks for them (`madvise`, its default mode) before it is first
//! written; Embree asks for them the same way.

/// A huge page's size: only the huge-page-aligned whole ones inside an array can be huge.
const HUGE: usize = 2 << 20;

/// Arrays smaller than one huge page gain nothing.
const MIN_BYTES: usize = HUGE;

/// What glibc's `malloc` adds to a big request before mapping it (its chunk header,
/// rounded up): a request of a whole number of huge pages less this gets a mapping of
/// exactly that many huge pages, which Linux places on a huge-page boundary (measured
/// on this project's 6.18 kernels; elsewhere the mapping starts anywhere, as before).
const MALLOC_HEADER: usize = 32;

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
pub fn zeroed<T: bytemuck::Zeroable>(n: usize) -> Zeroed<T> {
    let size = std::mem::size_of::<T>().max(1);
    if n * size < MIN_BYTES {
        return Zeroed { buf: bytemuck::allocation::zeroed_vec(n), start: 0 };
    }
    // The allocator writes its header into the mapping's first huge page before it can
    // be advised, which leaves that page on 4 KiB pages: 512 faults at 1.6 to 2.7 µs
    // each, where a whole huge page costs 0.05 to 0.35 ms (measured in C on this
    // project's hosts). So the zeros start at the first huge-page boundary past the
    // header, the page before holding nothing else: the first render of the 800×800
    // room in a process took 765 page faults in all, now 255.
    let mut buf = advised(bytemuck::allocation::zeroed_vec(room_for::<T>(n + HUGE.div_ceil(size))));
    let start = ((buf.as_ptr() as usize).next_multiple_of(HUGE) - buf.as_ptr() as usize).div_ceil(size);
    buf.truncate(start + n);
    Zeroed { buf, start }
}

/// The values of `buf` from `start` on ([`zeroed`]): a slice of its memory that may begin
/// past its start, so as to begin on a huge page.
pub struct Zeroed<T> {
    buf: Vec<T>,
    start: usize,
}

impl<T> std::ops::Deref for Zeroed<T> {
    type Target = [T];
    fn deref(&self) -> &[T] {
        &self.buf[self.start..]
    }
}

impl<T> std::ops::DerefMut for Zeroed<T> {
    fn deref_mut(&mut self) -> &mut [T] {
        &mut self.buf[self.start..]
    }
}

impl<T> Zeroed<T> {
    /// The whole buffer and the index where the values start: hands the memory on
    /// (to numpy, say) without copying it.
    pub fn into_parts(self) -> (Vec<T>, usize) {
        (self.buf, self.start)
    }
}

/// A copy holds only the values.
impl<T: Clone> Clone for Zeroed<T> {
    fn clone(&self) -> Self {
        Zeroed { buf: self.to_vec(), start: 0 }
    }
}

impl<T: std::fmt::Debug> std::fmt::Debug for Zeroed<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        (**self).fmt(f)
    }
}

impl<T: PartialEq> PartialEq for Zeroed<T> {
    fn eq(&self, other: &Self) -> bool {
        **self == **other
    }
}

/// An empty vector with room for `n`, its memory advised for huge pages if it is big:
/// fill it without growing it past `n`, which would move it to memory not so advised.
/// Its first huge page stays on 4 KiB pages: the allocator writes its header there
/// before the advice, and a huge page is only given to a range nothing has touched
/// (so an array of one huge page or less gains nothing from it, whatever its rounding).
pub fn with_capacity<T>(n: usize) -> Vec<T> {
    advised(Vec::with_capacity(n))
}

/// Room for `n` values, rounded up for a big array to fill whole huge pages with its
/// allocator's header, so that its mapping also ends on a huge-page boundary: otherwise
/// the part after the last one stays on 4 KiB pages, up to 511 page faults. For films
/// only: the last huge page is then backed whole, up to 2 MiB more memory, which for an
/// acceleration structure would count against its bytes per primitive.
fn room_for<T>(n: usize) -> usize {
    let size = std::mem::size_of::<T>().max(1);
    if n * size < MIN_BYTES {
        return n;
    }
    ((n * size + MALLOC_HEADER).next_multiple_of(HUGE) - MALLOC_HEADER) / size
}

/// `v`, fresh and not yet written: its memory advised for huge pages if it is big enough.
fn advised<T>(v: Vec<T>) -> Vec<T> {
    let bytes = v.capacity() * std::mem::size_of::<T>();
    if bytes >= MIN_BYTES {
        advise_huge(v.as_ptr().cast::<u8>(), bytes);
    }
    v
}

/// Asks for huge pages for the pages that hold the `bytes` bytes from `start`, the partly
/// held ones at either end included: rounded inwards, the first and last huge page of a
/// mapping fitted by [`room_for`] would each be cut by a 4 KiB page left out. A hint: if
/// the kernel declines, nothing changes.
#[cfg(target_os = "linux")]
#[allow(unsafe_code)]
fn advise_huge(start: *const u8, bytes: usize) {
    // SAFETY: sysconf only reads a system constant.
    let page = unsafe { libc::sysconf(libc::_SC_PAGESIZE) };
    let page = if page > 0 { page as usize } else { return };
    let first = start as usize / page * page;
    let end = (start as usize + bytes).next_multiple_of(page);
    // SAFETY: every page of `first..end` holds bytes of an allocation this process owns,
    // so it is mapped; MADV_HUGEPAGE only changes how the kernel backs pages with memory
    // (also for the bytes of those pages outside the allocation, such as the allocator's
    // header): no mapping is added or removed and no byte's value changes, so no Rust
    // reference can observe it. Its result is ignored on purpose: on failure the pages
    // stay 4 KiB, as without the call.
    unsafe { libc::madvise(first as *mut libc::c_void, end - first, libc::MADV_HUGEPAGE) };
}

#[cfg(not(target_os = "linux"))]
fn advise_huge(_: *const u8, _: usize) {}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn big_arrays_get_room_for_whole_huge_pages_with_the_header() {
        assert_eq!(room_for::<[f32; 3]>(1000), 1000);
        for n in [800 * 800, 1 << 20, (HUGE - MALLOC_HEADER) / 12, 3_333_333] {
            let room = room_for::<[f32; 3]>(n);
            let request = room * 12 + MALLOC_HEADER;
            assert!(room >= n && request.next_multiple_of(HUGE) - request < 12, "{n}: whole huge pages");
            assert!((room - n) * 12 < HUGE, "{n}: at most one huge page more");
        }
        let film: Zeroed<[f32; 3]> = zeroed(800 * 800);
        assert_eq!(film.len(), 800 * 800);
        assert!(film.buf.capacity() == room_for::<[f32; 3]>(800 * 800 + HUGE / 12 + 1) && film.start <= HUGE / 12 + 1);
        assert!((film.as_ptr() as usize) % HUGE < 12, "starts at a huge page");
    }

    #[test]
    fn contents_survive_the_move_whatever_the_size() {
        for n in [0usize, 10, 3 << 20] {
            let v: Vec<u32> = (0..n as u32).map(|i| i.wrapping_mul(2654435761)).collect();
            assert_eq!(on_huge_pages(v.clone()), v);
            let z: Zeroed<u32> = zeroed(n);
            assert!(z.len() == n && z.iter().all(|&b| b == 0));
        }
    }
}
