//! The stack's high-water mark. With cortex-m-rt's `paint-stack` feature every word between
//! `_stack_end` (the top of `.bss`/`.uninit`) and `_stack_start` (the top of RAM, where
//! the stack begins) holds `STACK_PAINT_VALUE` when `main` starts; the stack grows down,
//! so the lowest word that no longer does marks the deepest the stack has gone.

use cortex_m_rt::STACK_PAINT_VALUE;

// Symbols of cortex-m-rt's link.x; only their addresses are used.
#[allow(unsafe_code)]
unsafe extern "C" {
    safe static _stack_start: u32;
    safe static _stack_end: u32;
}

/// Deepest stack use since reset, bytes (to the nearest word; a frame that happens to
/// write the paint value at its low end reads a word short).
#[must_use]
pub fn high_water_bytes() -> usize {
    let top = core::ptr::addr_of!(_stack_start) as usize;
    let mut addr = core::ptr::addr_of!(_stack_end) as usize;
    while addr < top && read_word(addr) == STACK_PAINT_VALUE {
        addr += 4;
    }
    top - addr
}

#[allow(unsafe_code)]
fn read_word(addr: usize) -> u32 {
    // SAFETY: callers pass word addresses in [_stack_end, _stack_start), RAM that link.x
    // reserves for the stack and asserts 4-aligned; single core, no interrupts enabled,
    // so nothing writes it concurrently. Words below the stack pointer are only read.
    unsafe { core::ptr::read_volatile(addr as *const u32) }
}
