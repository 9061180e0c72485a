//! Stack high-water measurement by painting: fill the unused stack with a pattern early,
//! later find the lowest word that no longer holds it.
//!
//! cortex-m-rt places the stack at the top of RAM (`_stack_start`) growing down to
//! `_stack_end`, the end of `.bss`/`.uninit`. Everything between `_stack_end` and a margin
//! below the current stack pointer is painted; nothing there is in use when [`paint`] runs.

use core::ptr::{addr_of, read_volatile, write_volatile};

const PAINT: u32 = 0xC0DE_57AC;
/// Words left unpainted below this function's own stack pointer. Nothing below the stack
/// pointer is live (no interrupts are enabled while painting), so this is only a guard.
const MARGIN_WORDS: usize = 4;

unsafe extern "C" {
    static _stack_start: u32;
    static _stack_end: u32;
}

fn top() -> usize {
    // Only the address of the linker symbol is taken (no read): safe.
    addr_of!(_stack_start) as usize
}

fn bottom() -> usize {
    // Only the address of the linker symbol is taken (no read): safe.
    addr_of!(_stack_end) as usize
}

/// The stack's size in bytes.
pub fn size() -> usize {
    top() - bottom()
}

/// Current stack depth in bytes (top minus the stack pointer).
pub fn depth() -> usize {
    top().saturating_sub(cortex_m::register::msp::read() as usize)
}

/// Paints the free stack below the current stack pointer.
#[inline(never)]
pub fn paint() {
    let sp = cortex_m::register::msp::read() as usize;
    let end = sp.saturating_sub(MARGIN_WORDS * 4) & !3;
    let mut p = (bottom() + 3) & !3;
    while p < end {
        // SAFETY: [bottom, end) is RAM reserved for the stack and below every live frame.
        unsafe { write_volatile(p as *mut u32, PAINT) };
        p += 4;
    }
}

/// Deepest stack use since [`paint`], in bytes from the top: the lowest word that lost the
/// pattern. (A frame that happened to write the pattern value itself would be missed; the
/// value is chosen to be unlikely.)
pub fn high_water() -> usize {
    let mut p = (bottom() + 3) & !3;
    let t = top();
    while p < t {
        // SAFETY: reading stack RAM between the linker's bounds.
        if unsafe { read_volatile(p as *const u32) } != PAINT {
            break;
        }
        p += 4;
    }
    t - p
}
