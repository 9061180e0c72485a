//! A simulated ICM-42688-P behind `SpiDevice`, fed from a [`SampleSource`].
//!
//! It models what the driver relies on, from the datasheet: the `WHO_AM_I` value, soft reset
//! to reset values with `RESET_DONE_INT`, clear-on-read `INT_STATUS`, the full-scale fields of
//! `GYRO_CONFIG0` and `ACCEL_CONFIG0`, `PWR_MGMT0` gyro and accelerometer modes, big-endian
//! data registers (accelerometer at `ACCEL_DATA_X1`, gyro right after) that read -32768 while
//! their sensor is off, address auto-increment on burst reads, bit 7 of the address byte as the read
//! flag. Bank selection is stored; only bank 0 holds registers.
//!
//! Time is not simulated: the part is always one sample ahead of the reader. Each read of
//! `INT_STATUS` with the gyro on latches the next sample of the source into the data registers
//! and reports `DATA_RDY_INT`, as a real part does when the loop polls slower than the ODR
//! with a fresh sample waiting. When the source is exhausted `DATA_RDY_INT` stays clear, so
//! the driver times out, and [`SimIcm42688::exhausted`] tells the caller the log has ended.
//!
//! Samples are encoded at the configured full scale by [`crate::config::rad_s_to_raw`]:
//! rounding to the nearest count and clipping at +-32767, the quantisation of the real part.
//! A bus error can be injected on every n-th transaction to exercise error paths.

use embedded_hal::spi::{self, ErrorKind, ErrorType, Operation, SpiDevice};

use crate::config::{m_s2_to_raw, rad_s_to_raw, AccelFullScale, GyroFullScale};
use crate::registers as reg;

/// Where the simulated part's samples come from (rad/s, sensor axes): a recorded log, a
/// simulator, a test vector. `None` ends the stream.
pub trait SampleSource {
    /// The next gyro sample, or `None` at the end.
    fn next_sample(&mut self) -> Option<[f32; 3]>;

    /// The next sample of both sensors: `(gyro rad/s, accel m/s^2)`, or `None` at the end.
    /// By default the gyro sample with a zero specific force (free fall, the body in free
    /// flight); sources with accelerometer data override it.
    fn next_imu(&mut self) -> Option<([f32; 3], [f32; 3])> {
        self.next_sample().map(|g| (g, [0.0; 3]))
    }
}

impl<F: FnMut() -> Option<[f32; 3]>> SampleSource for F {
    fn next_sample(&mut self) -> Option<[f32; 3]> {
        self()
    }
}

/// The simulated bus error.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SimBusError;

impl spi::Error for SimBusError {
    fn kind(&self) -> ErrorKind {
        ErrorKind::Other
    }
}

/// Register values after reset that the driver reads (datasheet, section 14).
fn reset_registers() -> [u8; 128] {
    let mut r = [0u8; 128];
    let set = |r: &mut [u8; 128], a: u8, v: u8| {
        if let Some(x) = r.get_mut(usize::from(a)) {
            *x = v;
        }
    };
    set(&mut r, reg::WHO_AM_I, reg::WHO_AM_I_VALUE);
    set(&mut r, reg::INT_STATUS, reg::INT_STATUS_RESET_DONE);
    set(&mut r, reg::GYRO_CONFIG0, 0x06);
    set(&mut r, reg::ACCEL_CONFIG0, 0x06);
    set(&mut r, reg::INT_CONFIG1, reg::INT_CONFIG1_ASYNC_RESET);
    set(&mut r, reg::INT_SOURCE0, 0x10);
    set(&mut r, reg::FIFO_CONFIG1, 0x00);
    set(&mut r, reg::INTF_CONFIG0, 0x30); // big-endian data and FIFO count
    r
}

/// Registers whose value the simulated part keeps as written (the others are read-only or
/// have side effects handled separately).
const WRITABLE: [u8; 9] = [
    reg::INT_CONFIG,
    reg::FIFO_CONFIG,
    reg::PWR_MGMT0,
    reg::GYRO_CONFIG0,
    reg::ACCEL_CONFIG0,
    reg::FIFO_CONFIG1,
    reg::INT_CONFIG1,
    reg::INT_SOURCE0,
    reg::INTF_CONFIG0,
];

/// Counts of what the simulated part saw.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SimStats {
    /// SPI transactions, failed ones included.
    pub transactions: u32,
    /// Samples latched from the source.
    pub samples: u32,
    /// Injected bus errors.
    pub injected_errors: u32,
}

/// A simulated ICM-42688-P on SPI.
#[derive(Debug)]
pub struct SimIcm42688<S> {
    regs: [u8; 128],
    bank: u8,
    source: S,
    exhausted: bool,
    fail_every: u32,
    stats: SimStats,
}

impl<S: SampleSource> SimIcm42688<S> {
    /// A part just powered up, streaming from `source`.
    pub fn new(source: S) -> Self {
        SimIcm42688 {
            regs: reset_registers(),
            bank: 0,
            source,
            exhausted: false,
            fail_every: 0,
            stats: SimStats::default(),
        }
    }

    /// Fails every `n`-th SPI transaction with [`SimBusError`] (0: never).
    pub fn with_bus_error_every(mut self, n: u32) -> Self {
        self.fail_every = n;
        self
    }

    /// True once the source has returned `None`.
    pub fn exhausted(&self) -> bool {
        self.exhausted
    }

    /// What the part has seen so far.
    pub fn stats(&self) -> SimStats {
        self.stats
    }

    /// The sample source.
    pub fn source(&self) -> &S {
        &self.source
    }

    fn get(&self, a: u8) -> u8 {
        self.regs.get(usize::from(a)).copied().unwrap_or(0)
    }

    fn set(&mut self, a: u8, v: u8) {
        if let Some(x) = self.regs.get_mut(usize::from(a)) {
            *x = v;
        }
    }

    fn gyro_on(&self) -> bool {
        self.get(reg::PWR_MGMT0) & reg::PWR_MGMT0_GYRO_MASK != 0
    }

    fn accel_on(&self) -> bool {
        self.get(reg::PWR_MGMT0) & reg::PWR_MGMT0_ACCEL_MASK != 0
    }

    fn full_scale(&self) -> GyroFullScale {
        GyroFullScale::from_bits(self.get(reg::GYRO_CONFIG0) >> 5)
    }

    fn accel_full_scale(&self) -> AccelFullScale {
        AccelFullScale::from_bits(self.get(reg::ACCEL_CONFIG0) >> 5)
    }

    fn latch_at(&mut self, first: u8, raw: [i16; 3]) {
        for (i, v) in raw.iter().enumerate() {
            let [hi, lo] = v.to_be_bytes();
            let a = first + 2 * i as u8;
            self.set(a, hi);
            self.set(a + 1, lo);
        }
    }

    fn read_register(&mut self, a: u8) -> u8 {
        if a == reg::REG_BANK_SEL {
            return self.bank;
        }
        if self.bank != 0 {
            return 0;
        }
        match a {
            reg::INT_STATUS => {
                let mut status = self.get(reg::INT_STATUS);
                self.set(reg::INT_STATUS, 0);
                if self.gyro_on() && !self.exhausted {
                    match self.source.next_imu() {
                        Some((w, acc)) => {
                            let fs = self.full_scale();
                            self.latch_at(reg::GYRO_DATA_X1, w.map(|x| rad_s_to_raw(x, fs)));
                            let afs = self.accel_full_scale();
                            self.latch_at(reg::ACCEL_DATA_X1, acc.map(|x| m_s2_to_raw(x, afs)));
                            self.stats.samples = self.stats.samples.saturating_add(1);
                            status |= reg::INT_STATUS_DATA_RDY;
                        }
                        None => self.exhausted = true,
                    }
                }
                status
            }
            a if ((reg::GYRO_DATA_X1..reg::GYRO_DATA_X1 + 6).contains(&a) && !self.gyro_on())
                || ((reg::ACCEL_DATA_X1..reg::ACCEL_DATA_X1 + 6).contains(&a)
                    && !self.accel_on()) =>
            {
                let [hi, lo] = reg::INVALID_SAMPLE.to_be_bytes();
                // Both blocks start at an odd address: the high byte is at the odd ones.
                if !a.is_multiple_of(2) {
                    hi
                } else {
                    lo
                }
            }
            // Gyro-only FIFO is not simulated: it stays empty.
            reg::FIFO_COUNTH | 0x2F => 0,
            reg::FIFO_DATA => reg::FIFO_HEADER_EMPTY,
            a => self.get(a),
        }
    }

    fn write_register(&mut self, a: u8, v: u8) {
        if a == reg::REG_BANK_SEL {
            self.bank = v & 0b111;
            return;
        }
        if self.bank != 0 {
            return;
        }
        if a == reg::DEVICE_CONFIG && v & reg::DEVICE_CONFIG_SOFT_RESET != 0 {
            self.regs = reset_registers();
            self.bank = 0;
        } else if WRITABLE.contains(&a) {
            self.set(a, v);
        }
    }
}

impl<S> ErrorType for SimIcm42688<S> {
    type Error = SimBusError;
}

impl<S: SampleSource> SpiDevice for SimIcm42688<S> {
    /// One chip-select-framed transfer: the first byte written is the address byte (bit 7 =
    /// read); further written bytes are data for consecutive registers, reads return
    /// consecutive registers (auto-increment, except `FIFO_DATA`).
    fn transaction(&mut self, operations: &mut [Operation<'_, u8>]) -> Result<(), SimBusError> {
        self.stats.transactions = self.stats.transactions.wrapping_add(1);
        if self.fail_every != 0 && self.stats.transactions.is_multiple_of(self.fail_every) {
            self.stats.injected_errors = self.stats.injected_errors.saturating_add(1);
            return Err(SimBusError);
        }
        let mut address: Option<(u8, bool)> = None;
        for op in operations.iter_mut() {
            match op {
                Operation::Write(bytes) => {
                    for &b in bytes.iter() {
                        match address {
                            None => address = Some((b & 0x7F, b & reg::SPI_READ != 0)),
                            Some((a, false)) => {
                                self.write_register(a, b);
                                address = Some((a.wrapping_add(1) & 0x7F, false));
                            }
                            // Bytes clocked out during a read are ignored by the part.
                            Some((_, true)) => {}
                        }
                    }
                }
                Operation::Read(buf) => {
                    for b in buf.iter_mut() {
                        *b = match address {
                            Some((a, true)) => {
                                let v = self.read_register(a);
                                if a != reg::FIFO_DATA {
                                    address = Some((a.wrapping_add(1) & 0x7F, true));
                                }
                                v
                            }
                            _ => 0,
                        };
                    }
                }
                Operation::Transfer(rx, tx) => {
                    // Full duplex: the first tx byte is the address, rx mirrors reads.
                    for (i, r) in rx.iter_mut().enumerate() {
                        let t = tx.get(i).copied().unwrap_or(0);
                        *r = match address {
                            None => {
                                address = Some((t & 0x7F, t & reg::SPI_READ != 0));
                                0
                            }
                            Some((a, true)) => {
                                let v = self.read_register(a);
                                address = Some((a.wrapping_add(1) & 0x7F, true));
                                v
                            }
                            Some((a, false)) => {
                                self.write_register(a, t);
                                address = Some((a.wrapping_add(1) & 0x7F, false));
                                0
                            }
                        };
                    }
                }
                Operation::TransferInPlace(buf) => {
                    for b in buf.iter_mut() {
                        let t = *b;
                        *b = match address {
                            None => {
                                address = Some((t & 0x7F, t & reg::SPI_READ != 0));
                                0
                            }
                            Some((a, true)) => {
                                let v = self.read_register(a);
                                address = Some((a.wrapping_add(1) & 0x7F, true));
                                v
                            }
                            Some((a, false)) => {
                                self.write_register(a, t);
                                address = Some((a.wrapping_add(1) & 0x7F, false));
                                0
                            }
                        };
                    }
                }
                Operation::DelayNs(_) => {}
            }
        }
        Ok(())
    }
}

// ---------------------------------------------------------------------------------------------
// Fault injection between the driver and the simulated part.

/// The randomness of [`FaultySpi`]: any source of uniform 32-bit words. A closure
/// `FnMut() -> u32` is one (on the host, e.g. a seeded `rand` generator's `next_u32`);
/// [`XorShift32`] is a small one for the MCU.
pub trait FaultRng {
    /// The next uniform 32-bit word.
    fn next_u32(&mut self) -> u32;

    /// True with probability `ppm` per million (never for 0).
    fn chance(&mut self, ppm: u32) -> bool {
        ppm != 0 && self.next_u32() % 1_000_000 < ppm
    }
}

impl<F: FnMut() -> u32> FaultRng for F {
    fn next_u32(&mut self) -> u32 {
        self()
    }
}

/// Marsaglia's xorshift32: seeded, reproducible, no_std.
#[derive(Clone, Copy, Debug)]
pub struct XorShift32(pub u32);

impl XorShift32 {
    /// A generator from `seed` (made odd, so never the all-zero state).
    pub const fn new(seed: u32) -> Self {
        XorShift32(seed | 1)
    }
}

impl FaultRng for XorShift32 {
    fn next_u32(&mut self) -> u32 {
        let mut x = self.0;
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        self.0 = x;
        x
    }
}

/// Which faults [`FaultySpi`] injects, how often. Windows are in SPI transactions
/// `[from, to)` (counted from 1).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Faults {
    /// Per million transactions: the transaction fails with a bus error.
    pub bus_error_ppm: u32,
    /// Per million gyro data reads: one of the 48 gyro bits is flipped.
    pub corrupt_ppm: u32,
    /// Per million data-ready events: lost (the sample is gone, the part moves on).
    pub drop_ppm: u32,
    /// Every transaction fails.
    pub bus_dead: Option<(u32, u32)>,
    /// `WHO_AM_I` reads 0x00.
    pub wrong_id: Option<(u32, u32)>,
    /// `DATA_RDY_INT` is never set.
    pub no_data_ready: Option<(u32, u32)>,
    /// The data registers repeat the last sample read.
    pub stalled: Option<(u32, u32)>,
    /// This transaction never completes (spins forever: for a watchdog test).
    pub hang: Option<u32>,
}

/// What [`FaultySpi`] injected.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Injected {
    /// Transactions failed.
    pub bus_errors: u32,
    /// Data reads with a flipped bit.
    pub corrupted: u32,
    /// Data-ready events lost.
    pub dropped: u32,
}

/// The simulated part behind a fault-injecting SPI layer: seeded bus errors, bit flips in the
/// gyro data, lost data-ready events, and windows of a dead bus, a wrong identity, no
/// data-ready, stalled data, or a hung transfer. Used by the host robustness test and the QEMU
/// fault check alike. The driver frames every read as `[Write([addr | 0x80]), Read(buf)]`;
/// data reads are the 12-byte accel + gyro burst or the 6-byte gyro read.
#[derive(Debug)]
pub struct FaultySpi<S, R> {
    /// The simulated part.
    pub inner: SimIcm42688<S>,
    faults: Faults,
    rng: R,
    tx: u32,
    stalled_data: Option<[u8; reg::IMU_BURST_LEN]>,
    injected: Injected,
}

fn within(w: Option<(u32, u32)>, t: u32) -> bool {
    w.is_some_and(|(a, b)| a <= t && t < b)
}

impl<S, R> FaultySpi<S, R> {
    /// `inner` behind `faults`, drawing from `rng`.
    pub fn new(inner: SimIcm42688<S>, faults: Faults, rng: R) -> Self {
        FaultySpi {
            inner,
            faults,
            rng,
            tx: 0,
            stalled_data: None,
            injected: Injected::default(),
        }
    }

    /// What was injected so far.
    pub fn injected(&self) -> Injected {
        self.injected
    }

    /// Transactions so far.
    pub fn transactions(&self) -> u32 {
        self.tx
    }
}

impl<S, R> ErrorType for FaultySpi<S, R> {
    type Error = SimBusError;
}

impl<S: SampleSource, R: FaultRng> SpiDevice for FaultySpi<S, R> {
    fn transaction(&mut self, ops: &mut [Operation<'_, u8>]) -> Result<(), SimBusError> {
        self.tx = self.tx.wrapping_add(1);
        let t = self.tx;
        if self.faults.hang == Some(t) {
            #[cfg(feature = "defmt")]
            defmt::warn!("injected: SPI transfer {=u32} hangs", t);
            loop {
                core::hint::spin_loop();
            }
        }
        if within(self.faults.bus_dead, t) || self.rng.chance(self.faults.bus_error_ppm) {
            self.injected.bus_errors = self.injected.bus_errors.saturating_add(1);
            return Err(SimBusError);
        }
        let addr = match ops.first() {
            Some(Operation::Write(b)) => b.first().copied(),
            _ => None,
        };
        self.inner.transaction(ops)?;
        let Some(a) = addr.filter(|a| a & reg::SPI_READ != 0).map(|a| a & 0x7F) else {
            return Ok(());
        };
        let Some(Operation::Read(buf)) = ops.get_mut(1) else {
            return Ok(());
        };
        // Where the gyro's six bytes are in a data read.
        let gyro_at = match (a, buf.len()) {
            (reg::ACCEL_DATA_X1, reg::IMU_BURST_LEN) => Some(6),
            (reg::GYRO_DATA_X1, 6) => Some(0),
            _ => None,
        };
        match (a, gyro_at) {
            (reg::WHO_AM_I, _) if within(self.faults.wrong_id, t) => buf.fill(0),
            (reg::INT_STATUS, _) => {
                let ready = buf
                    .first()
                    .is_some_and(|b| b & reg::INT_STATUS_DATA_RDY != 0);
                if ready
                    && (within(self.faults.no_data_ready, t)
                        || self.rng.chance(self.faults.drop_ppm))
                {
                    if let Some(b) = buf.first_mut() {
                        *b &= !reg::INT_STATUS_DATA_RDY;
                    }
                    self.injected.dropped = self.injected.dropped.saturating_add(1);
                }
            }
            (_, Some(at)) => {
                if within(self.faults.stalled, t) {
                    let mut h = [0u8; reg::IMU_BURST_LEN];
                    for (d, s) in h.iter_mut().zip(buf.iter()) {
                        *d = *s;
                    }
                    let held = *self.stalled_data.get_or_insert(h);
                    for (d, s) in buf.iter_mut().zip(held.iter()) {
                        *d = *s;
                    }
                } else {
                    self.stalled_data = None;
                    if self.rng.chance(self.faults.corrupt_ppm) {
                        let bit = (self.rng.next_u32() % 48) as usize;
                        if let Some(b) = buf.get_mut(at + bit / 8) {
                            *b ^= 1 << (bit % 8);
                        }
                        self.injected.corrupted = self.injected.corrupted.saturating_add(1);
                    }
                }
            }
            _ => {}
        }
        Ok(())
    }
}
