//! A fixed array that the kernel may back with 2 MiB pages.
//!
//! The tracer's nodes and triangle packs are read at random: a builder ray
//! of San Francisco touches about a dozen of them, spread over 22 MB. With
//! 4 KiB pages each is likely a TLB miss (a page walk); with 2 MiB pages
//! the whole tree needs a dozen TLB entries. Linux gives an anonymous
//! region huge pages when it is told to (`madvise(MADV_HUGEPAGE)`, which
//! counts where transparent huge pages are set to `madvise`, Debian's
//! default) before the pages are first touched, as Embree does for its
//! BVHs (seen here: an Embree build of San Francisco holds 106 MB of
//! `AnonHugePages`). Off Linux, or below 1 MiB, the array is an ordinary
//! allocation; where the kernel declines the advice, the mapping has
//! ordinary pages; nothing else changes (notes/trace.md, step 6).

use std::alloc::{self, Layout};
use std::ptr::NonNull;

/// The size of a huge page, and the alignment of mapped arrays.
const HUGE: usize = 2 << 20;

/// A boxed slice of `T`, in fresh memory advised for huge pages (2 MiB
/// aligned) where it is at least 1 MiB and the system is Linux.
pub(super) struct HugeArray<T: Copy> {
    ptr: NonNull<T>,
    len: usize,
    memory: Memory,
}

/// Where a [`HugeArray`]'s elements live.
enum Memory {
    /// Nothing allocated (no elements, or zero-sized ones).
    None,
    /// The global allocator's, with this layout.
    Heap(Layout),
    /// An anonymous mapping of ours: its start and length.
    #[cfg_attr(not(target_os = "linux"), allow(dead_code))]
    Mapped(*mut u8, usize),
}

// SAFETY: a HugeArray owns its elements as a `Box<[T]>` would.
unsafe impl<T: Copy + Send> Send for HugeArray<T> {}
// SAFETY: shared access only reads, as for `&[T]`.
unsafe impl<T: Copy + Sync> Sync for HugeArray<T> {}

impl<T: Copy> HugeArray<T> {
    /// A copy of `items`.
    ///
    /// # Panics
    /// When the size overflows `isize` (as `Vec` would).
    pub(super) fn from_slice(items: &[T]) -> Self {
        let bytes = std::mem::size_of_val(items);
        let (raw, memory) = if bytes == 0 {
            (NonNull::<T>::dangling().as_ptr().cast::<u8>(), Memory::None)
        } else if let Some((raw, len)) = map_huge(bytes, align_of::<T>()) {
            (raw, Memory::Mapped(raw, len))
        } else {
            let layout =
                Layout::array::<T>(items.len()).expect("an array of at most isize::MAX bytes");
            // SAFETY: the layout's size is not zero.
            (unsafe { alloc::alloc(layout) }, Memory::Heap(layout))
        };
        let Some(ptr) = NonNull::new(raw.cast::<T>()) else {
            alloc::handle_alloc_error(Layout::array::<T>(items.len()).expect("checked above"))
        };
        // SAFETY: the memory holds `items.len()` elements of `T`, aligned,
        // and does not overlap `items` (nothing to copy when empty).
        unsafe { std::ptr::copy_nonoverlapping(items.as_ptr(), ptr.as_ptr(), items.len()) };
        Self {
            ptr,
            len: items.len(),
            memory,
        }
    }
}

/// A fresh anonymous mapping of at least `bytes` (rounded up to whole
/// huge pages, 2 MiB aligned), advised for huge pages before any page of
/// it is touched; `None` below 1 MiB, where `align` exceeds a huge page,
/// or when the kernel refuses the mapping.
#[cfg(target_os = "linux")]
fn map_huge(bytes: usize, align: usize) -> Option<(*mut u8, usize)> {
    if bytes < HUGE / 2 || align > HUGE {
        return None;
    }
    let len = bytes.checked_next_multiple_of(HUGE)?;
    // SAFETY: an anonymous private mapping at an address of the kernel's
    // choosing, of a length that is not zero, aliases nothing.
    let base = unsafe {
        libc::mmap(
            std::ptr::null_mut(),
            len + HUGE,
            libc::PROT_READ | libc::PROT_WRITE,
            libc::MAP_PRIVATE | libc::MAP_ANONYMOUS,
            -1,
            0,
        )
    };
    if base == libc::MAP_FAILED {
        return None;
    }
    // Keep the 2 MiB aligned `len` bytes inside; give back the rest.
    let base = base.cast::<u8>();
    let skip = base.align_offset(HUGE);
    // SAFETY: both ranges lie in the mapping just made, are page aligned
    // (mmap's start and `skip` are multiples of the page size) and are
    // not used by anything.
    unsafe {
        let start = base.add(skip);
        if skip > 0 {
            libc::munmap(base.cast(), skip);
        }
        libc::munmap(start.add(len).cast(), HUGE - skip);
        // A request only: the mapping works whatever the answer.
        libc::madvise(start.cast(), len, libc::MADV_HUGEPAGE);
        Some((start, len))
    }
}

#[cfg(not(target_os = "linux"))]
fn map_huge(_bytes: usize, _align: usize) -> Option<(*mut u8, usize)> {
    None
}

impl<T: Copy> std::ops::Deref for HugeArray<T> {
    type Target = [T];

    fn deref(&self) -> &[T] {
        // SAFETY: `ptr` holds `len` initialised elements (or is dangling
        // and aligned with nothing to read), alive as long as `self`.
        unsafe { std::slice::from_raw_parts(self.ptr.as_ptr(), self.len) }
    }
}

impl<T: Copy> Drop for HugeArray<T> {
    fn drop(&mut self) {
        match self.memory {
            Memory::None => {}
            // SAFETY: allocated in `from_slice` with this layout; `T` is
            // `Copy`, so there is nothing to drop first.
            Memory::Heap(layout) => unsafe { alloc::dealloc(self.ptr.as_ptr().cast(), layout) },
            #[cfg(target_os = "linux")]
            // SAFETY: our own mapping, unmapped once; nothing borrows it
            // past `self`.
            Memory::Mapped(start, len) => unsafe {
                libc::munmap(start.cast(), len);
            },
            #[cfg(not(target_os = "linux"))]
            Memory::Mapped(..) => unreachable!("mapped only on Linux"),
        }
    }
}

impl<T: Copy + std::fmt::Debug> std::fmt::Debug for HugeArray<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_list().entries(self.iter()).finish()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn holds_a_copy_of_any_size() {
        for n in [0usize, 1, 7, 100_000, 300_000, 1 << 20] {
            let items: Vec<u64> = (0..n as u64).map(|i| i * 3 + 1).collect();
            let a = HugeArray::from_slice(&items);
            assert_eq!(&*a, &items[..]);
            if cfg!(target_os = "linux") && n * 8 >= HUGE / 2 {
                assert_eq!(a.as_ptr() as usize % HUGE, 0, "{n} elements: 2 MiB aligned");
            }
        }
        let empty: HugeArray<[f32; 3]> = HugeArray::from_slice(&[]);
        assert!(empty.is_empty());
        let zst = HugeArray::from_slice(&[(); 5]);
        assert_eq!(zst.len(), 5);
    }
}
