//! Time: the loop's sample clock and a delay that does not wait.

use embedded_hal::delay::DelayNs;

/// A delay that does not wait: for the simulated part, which models no time (it always has
/// the next sample ready), under QEMU and on the host.
#[derive(Clone, Copy, Debug, Default)]
pub struct NoDelay;

impl DelayNs for NoDelay {
    fn delay_ns(&mut self, _ns: u32) {}
}

/// The loop's time base: a free-running clock in microseconds (wrapping at `2^32`), read once
/// per sample. Samples lost on the way (data-ready missed, bus errors) then lengthen the next
/// step instead of shrinking the time base, as counting data-ready events would.
///
/// The elapsed time between two samples is rounded to whole sample periods (at least one), so
/// the clock needs only be good to a fraction of a period. On a board: a timer or the cycle
/// counter; on the simulated part, which models no time: its count of latched samples times
/// the period. Any `FnMut(&IF) -> u32` is a clock (the argument is the driver's bus
/// interface, for the simulated part).
pub trait SampleClock<IF> {
    /// Microseconds since an arbitrary origin, wrapping.
    fn now_us(&mut self, interface: &IF) -> u32;
}

impl<IF, F: FnMut(&IF) -> u32> SampleClock<IF> for F {
    fn now_us(&mut self, interface: &IF) -> u32 {
        self(interface)
    }
}
