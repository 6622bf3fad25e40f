//! Stack high-water mark: paint the free stack, later find the deepest
//! word the program overwrote. The core lives on `main`'s stack, so this
//! is most of its RAM use (`.data` + `.bss` are nearly empty).

use core::ptr::{addr_of, read_volatile, write_volatile};
use core::sync::atomic::{AtomicUsize, Ordering};

/// The paint (cortex-m-rt's `paint-stack` value).
const PAINT: u32 = 0xCCCC_CCCC;
/// How far below the current stack pointer to paint (the rest is not measured).
pub const PAINT_SPAN: usize = 64 * 1024;
/// Left alone below the stack pointer, for `paint`'s own frame.
const GUARD: usize = 256;

/// The range [`paint`] painted, `[low, high)`.
static PAINTED_LOW: AtomicUsize = AtomicUsize::new(0);
static PAINTED_HIGH: AtomicUsize = AtomicUsize::new(0);

extern "C" {
    /// Top of the stack (end of RAM), from cortex-m-rt's `link.x`.
    static _stack_start: u32;
    /// Lowest address the stack may use, from cortex-m-rt's `link.x`.
    static _stack_end: u32;
}

/// Paints the unused stack below the current stack pointer (call once, first).
#[inline(never)]
pub fn paint() {
    let sp = cortex_m::register::msp::read() as usize;
    let high = (sp - GUARD) & !3;
    let low = high
        .saturating_sub(PAINT_SPAN)
        .max(addr_of!(_stack_end) as usize);
    PAINTED_LOW.store(low, Ordering::Relaxed);
    PAINTED_HIGH.store(high, Ordering::Relaxed);
    let mut addr = low;
    while addr < high {
        // SAFETY: below the live stack (with a guard for this frame) and
        // above `_stack_end`: RAM nothing uses yet; no interrupts are enabled.
        unsafe { write_volatile(addr as *mut u32, PAINT) };
        addr += 4;
    }
}

/// Deepest stack use since [`paint`], bytes from the top of RAM; `None` if the
/// whole painted span was used (the stack went deeper than measured).
pub fn high_water_bytes() -> Option<usize> {
    let top = addr_of!(_stack_start) as usize;
    let (low, high) = (
        PAINTED_LOW.load(Ordering::Relaxed),
        PAINTED_HIGH.load(Ordering::Relaxed),
    );
    let mut addr = low;
    // SAFETY: reads of RAM in the painted range.
    while addr < high && unsafe { read_volatile(addr as *const u32) } == PAINT {
        addr += 4;
    }
    (addr > low).then(|| top - addr)
}
