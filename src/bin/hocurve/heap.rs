//! The heap in use, counted by a global allocator around the system's one:
//! its peak between two points of a run is what `hocurve bench` reports as
//! the memory of each phase. Two relaxed atomic operations per allocation.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering::Relaxed};

/// The system allocator, counting.
pub struct Counting;

static IN_USE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

fn grow(n: usize) {
    let now = IN_USE.fetch_add(n, Relaxed) + n;
    PEAK.fetch_max(now, Relaxed);
}

fn shrink(n: usize) {
    IN_USE.fetch_sub(n, Relaxed);
}

// SAFETY: every call is forwarded to `System` with the same arguments; the
// counters do not touch the memory.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let p = unsafe { System.alloc(layout) };
        if !p.is_null() {
            grow(layout.size());
        }
        p
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        let p = unsafe { System.alloc_zeroed(layout) };
        if !p.is_null() {
            grow(layout.size());
        }
        p
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) };
        shrink(layout.size());
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let p = unsafe { System.realloc(ptr, layout, new_size) };
        if !p.is_null() {
            if new_size >= layout.size() {
                grow(new_size - layout.size());
            } else {
                shrink(layout.size() - new_size);
            }
        }
        p
    }
}

/// Bytes allocated and not yet freed.
pub fn in_use() -> usize {
    IN_USE.load(Relaxed)
}

/// The most bytes in use at once since the last [`reset_peak`].
pub fn peak() -> usize {
    PEAK.load(Relaxed).max(in_use())
}

/// Start a new peak from the bytes in use now.
pub fn reset_peak() {
    PEAK.store(in_use(), Relaxed);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_buffer_raises_the_peak_by_its_size_and_freeing_it_lowers_the_use() {
        // Other tests allocate on other threads: the margins allow for them.
        reset_peak();
        let before = in_use();
        let v = vec![1u8; 64 << 20];
        assert!(in_use() >= before + (64 << 20) - (8 << 20), "{} {}", in_use(), before);
        assert!(peak() >= before + (64 << 20) - (8 << 20));
        drop(v);
        assert!(in_use() < before + (8 << 20), "{} {}", in_use(), before);
        assert!(peak() >= before + (64 << 20) - (8 << 20), "the peak stays");
        reset_peak();
        assert!(peak() < before + (8 << 20));
    }
}
