//! Time: the loop's sample clock and a delay that does not wait.

use embedded_hal::delay::DelayNs;
use icm42688::Config;

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

/// The loop's time base: sample periods counted by a [`SampleClock`].
#[derive(Clone, Copy, Debug)]
pub(crate) struct SampleTime {
    /// Nominal sample period, s.
    period: f32,
    /// Nominal sample period, us.
    period_us: u32,
    /// The clock at the last sample read.
    last_us: u32,
    /// Sample periods since the start.
    tick: u32,
    /// The reports' rate, Hz: `tick / rate_hz` is the time in seconds.
    rate_hz: f32,
}

impl SampleTime {
    /// The time base of a gyro configured with `config`, counting seconds at `rate_hz`, the
    /// clock reading `now_us`.
    pub(crate) fn new(config: &Config, rate_hz: f32, now_us: u32) -> Self {
        SampleTime {
            period: config.odr.period_s(),
            period_us: config.odr.period_us().max(1),
            last_us: now_us,
            tick: 0,
            rate_hz,
        }
    }

    /// A sample read at the clock reading `now_us`: the whole sample periods since the
    /// previous one (rounded, at least one), added to the tick.
    pub(crate) fn advance(&mut self, now_us: u32) -> u32 {
        let elapsed = now_us.wrapping_sub(self.last_us);
        self.last_us = now_us;
        let mut periods = elapsed / self.period_us;
        if elapsed % self.period_us >= self.period_us / 2 {
            periods = periods.saturating_add(1);
        }
        let periods = periods.max(1);
        self.tick = self.tick.wrapping_add(periods);
        periods
    }

    /// One sample of a replay, which has no clock.
    pub(crate) fn advance_one(&mut self) {
        self.tick = self.tick.wrapping_add(1);
    }

    /// `periods` sample periods in seconds.
    pub(crate) fn seconds_of(&self, periods: u32) -> f32 {
        periods as f32 * self.period
    }

    /// Sample periods since the start.
    pub(crate) fn tick(&self) -> u32 {
        self.tick
    }

    /// Seconds since the start, `tick / rate_hz`.
    pub(crate) fn t(&self) -> f32 {
        // A division, so whole seconds print as such (3000 / 1000 is exactly 3.0).
        self.tick as f32 / self.rate_hz
    }
}
