//! glint's one integration-test binary: cross-crate checks against definitions.
//!
//! Sizes here fit `cargo test`; `cargo xtask validate` runs the same checkers at full size.

mod brdf;
mod dense;
mod density_maps;
mod doc_lists;
mod footprints;
mod lattice;
mod light_cones;
mod map_properties;
mod sphere;
mod stability;
mod surface_maps;
mod tree;

/// Counts heap allocations per thread, so a test can assert that queries allocate nothing.
mod counting_allocator {
    use std::alloc::{GlobalAlloc, Layout, System};
    use std::cell::Cell;

    thread_local! {
        static ALLOCATIONS: Cell<u64> = const { Cell::new(0) };
    }

    /// Allocations made so far by the current thread.
    pub(crate) fn allocations() -> u64 {
        ALLOCATIONS.with(Cell::get)
    }

    struct CountingAllocator;

    // SAFETY: forwards every call to the system allocator unchanged; the thread-local counter
    // is const-initialized and has no destructor, so touching it never allocates or recurses.
    #[allow(unsafe_code)]
    unsafe impl GlobalAlloc for CountingAllocator {
        unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
            ALLOCATIONS.with(|c| c.set(c.get() + 1));
            // SAFETY: the caller's contract for `alloc` is passed on unchanged.
            unsafe { System.alloc(layout) }
        }

        unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
            // SAFETY: `ptr` came from `System.alloc` with this layout.
            unsafe { System.dealloc(ptr, layout) }
        }

        unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
            ALLOCATIONS.with(|c| c.set(c.get() + 1));
            // SAFETY: as for `alloc` and `dealloc`.
            unsafe { System.realloc(ptr, layout, new_size) }
        }
    }

    #[global_allocator]
    static GLOBAL: CountingAllocator = CountingAllocator;
}
