//! A global allocator that staggers large blocks within the memory page.
//!
//! Large blocks come page-aligned (or at one fixed offset), so entry `i` of every vector of a grid lies at the
//! same offset within its page, and a loop that stores to one vector and then loads from another near the same
//! index waits on each such store until the processor has told the two addresses apart (4K aliasing).
//! [`Staggered`] starts each block of at least [`LARGE`] bytes at one of [`SLOTS`] offsets 256 bytes apart, in
//! turn, so vectors allocated one after the other lie at different offsets. The Python module installs it over
//! mimalloc (`docs/dev/ablation.md`).

use std::alloc::{GlobalAlloc, Layout};
use std::sync::atomic::{AtomicUsize, Ordering};

/// Blocks from this size on are staggered; smaller ones are the inner allocator's, unchanged.
pub const LARGE: usize = 1 << 16;
/// How many offsets blocks take in turn: 64 + 256·k bytes, k < `SLOTS`.
pub const SLOTS: usize = 15;
const STEP: usize = 256;
/// The extra bytes a staggered block takes (up to its largest offset); the offset is stored in the `usize` before it.
const ROOM: usize = 64 + STEP * (SLOTS - 1);

/// A global allocator over `A` that staggers large blocks (see the module's documentation).
#[derive(Debug)]
pub struct Staggered<A>(pub A);

static NEXT: AtomicUsize = AtomicUsize::new(0);

/// The inner allocator's block for a staggered one of layout `l`, or `None` where `l` is not staggered.
fn outer(l: Layout) -> Option<Layout> {
    if l.size() < LARGE || l.align() > 64 { return None; }
    Layout::from_size_align(l.size().checked_add(ROOM)?, 64).ok()
}

/// The block at the next offset into `base` (null stays null), its offset written before it.
#[allow(unsafe_code)]
unsafe fn place(base: *mut u8) -> *mut u8 {
    if base.is_null() { return base; }
    let off = 64 + STEP * (NEXT.fetch_add(1, Ordering::Relaxed) % SLOTS);
    // SAFETY: `base` is 64-aligned with at least `ROOM` ≥ `off` ≥ 64 bytes: `p` and the `usize` before it lie in it.
    unsafe {
        let p = base.add(off);
        p.cast::<usize>().sub(1).write(off);
        p
    }
}

/// The offset of staggered block `p` within its inner block.
#[allow(unsafe_code)]
unsafe fn offset(p: *mut u8) -> usize {
    // SAFETY: `p` came from `place`, which wrote its offset there.
    unsafe { p.cast::<usize>().sub(1).read() }
}

// SAFETY: every block is the inner allocator's, returned to it with the layout it was allocated with (`outer` of
// the same layout for a staggered one); a staggered block lies within its inner one and is 64-aligned.
#[allow(unsafe_code)]
unsafe impl<A: GlobalAlloc> GlobalAlloc for Staggered<A> {
    unsafe fn alloc(&self, l: Layout) -> *mut u8 {
        unsafe { outer(l).map_or_else(|| self.0.alloc(l), |o| place(self.0.alloc(o))) }
    }

    unsafe fn alloc_zeroed(&self, l: Layout) -> *mut u8 {
        unsafe { outer(l).map_or_else(|| self.0.alloc_zeroed(l), |o| place(self.0.alloc_zeroed(o))) }
    }

    unsafe fn dealloc(&self, p: *mut u8, l: Layout) {
        unsafe { outer(l).map_or_else(|| self.0.dealloc(p, l), |o| self.0.dealloc(p.sub(offset(p)), o)) }
    }

    unsafe fn realloc(&self, p: *mut u8, l: Layout, size: usize) -> *mut u8 {
        unsafe {
            // SAFETY: the caller guarantees `size`, rounded up to `l.align()`, does not overflow `isize`.
            let new = Layout::from_size_align_unchecked(size, l.align());
            match (outer(l), outer(new)) {
                // The inner realloc keeps the bytes, so the block keeps its offset and its record.
                (Some(o), Some(n)) => {
                    let off = offset(p);
                    let base = self.0.realloc(p.sub(off), o, n.size());
                    if base.is_null() { base } else { base.add(off) }
                }
                (None, None) => self.0.realloc(p, l, size),
                _ => {
                    let q = self.alloc(new);
                    if !q.is_null() {
                        std::ptr::copy_nonoverlapping(p, q, l.size().min(size));
                        self.dealloc(p, l);
                    }
                    q
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    #[allow(unsafe_code)]
    fn large_blocks_take_distinct_offsets_and_keep_their_bytes() {
        let a = Staggered(std::alloc::System);
        // SAFETY: every block is used within its layout and freed once with it.
        unsafe {
            let l = Layout::from_size_align(LARGE, 16).unwrap();
            let blocks: Vec<*mut u8> = (0..SLOTS).map(|_| a.alloc_zeroed(l)).collect();
            let mut offsets: Vec<usize> = blocks.iter().map(|&p| offset(p)).collect();
            assert!(blocks.iter().all(|&p| !p.is_null() && p as usize % 64 == 0));
            assert!(blocks.iter().all(|&p| std::slice::from_raw_parts(p, LARGE).iter().all(|&b| b == 0)));
            offsets.sort_unstable();
            assert_eq!(offsets, (0..SLOTS).map(|k| 64 + STEP * k).collect::<Vec<_>>(), "consecutive blocks, every offset once");
            // Grown, shrunk past the threshold and back: the bytes stay.
            // A pattern that does not repeat every `STEP` bytes: a block moved by whole slots would not match it.
            let mut p = a.alloc(l);
            (0..LARGE).for_each(|i| p.add(i).write((i % 251) as u8));
            let sizes = [LARGE, 3 * LARGE, 2 * LARGE, 100, 50, 2 * LARGE];
            for w in sizes.windows(2) {
                p = a.realloc(p, Layout::from_size_align(w[0], 16).unwrap(), w[1]);
                let kept = w[0].min(w[1]);
                assert!(!p.is_null() && (0..kept).all(|i| p.add(i).read() == (i % 251) as u8), "{} → {}", w[0], w[1]);
                (kept..w[1]).for_each(|i| p.add(i).write((i % 251) as u8));
            }
            a.dealloc(p, Layout::from_size_align(2 * LARGE, 16).unwrap());
            blocks[1..].iter().for_each(|&p| a.dealloc(p, l));
            // Small blocks and over-aligned ones are the inner allocator's.
            let small = Layout::from_size_align(1000, 8).unwrap();
            let q = a.alloc(small);
            a.dealloc(q, small);
            let aligned = Layout::from_size_align(LARGE, 4096).unwrap();
            let q = a.alloc(aligned);
            assert_eq!(q as usize % 4096, 0);
            a.dealloc(q, aligned);
        }
    }
}
