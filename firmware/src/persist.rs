//! The last good estimate across resets: a `sequential-storage` map (one key) on two erase
//! pages of NOR flash. On the STM32F405, sectors 10 and 11 (2 x 128 KiB at `0x080C_0000`,
//! reserved in `memory.x` as `STORAGE`, [`STM32F405_RANGE`]); on the host, tests use a RAM
//! flash that can lose power in the middle of a write.
//!
//! An estimate is committed when [`EstimateStore::save`] returns `true`: sequential-storage
//! writes each item with a CRC and only then counts it, so a reset during a write leaves the
//! previous committed estimate in place (`a_reset_in_the_middle_of_a_campaign_loses_no_
//! committed_estimate` below). Flash access on the MCU is synchronous, so the crate's futures
//! complete on their first poll; [`block_on`] polls them with a no-op waker.

use core::future::Future;
use core::ops::Range;
use core::pin::pin;
use core::task::{Context, Poll, Waker};

use embedded_storage_async::nor_flash::NorFlash;
use sequential_storage::cache::{Cache, Uncached};
use sequential_storage::map::{MapConfig, MapStorage};

/// Flash offsets (from `0x0800_0000`) of the two sectors reserved for the store.
pub const STM32F405_RANGE: Range<u32> = 0x000C_0000..0x0010_0000;
/// The one key.
const KEY: u8 = 1;
/// Work buffer: key, item, word alignment.
const BUF: usize = telemetry::MAX_ESTIMATE + 16;

/// Runs a future that never waits (flash operations that complete synchronously).
pub fn block_on<F: Future>(f: F) -> F::Output {
    let mut f = pin!(f);
    let mut cx = Context::from_waker(Waker::noop());
    loop {
        if let Poll::Ready(v) = f.as_mut().poll(&mut cx) {
            return v;
        }
    }
}

/// The persisted estimate.
pub struct EstimateStore<S: NorFlash> {
    map: MapStorage<u8, S, Cache<Uncached, Uncached, Uncached, u8>>,
}

impl<S: NorFlash> EstimateStore<S> {
    /// A store on `range` of `flash` (at least two erase pages, page-aligned); `None` if not.
    pub fn new(flash: S, range: Range<u32>) -> Option<Self> {
        let config = MapConfig::try_new(range).ok()?;
        Some(EstimateStore {
            map: MapStorage::new(flash, config, Cache::new_uncached()),
        })
    }

    /// The last committed estimate, if any (and if it decodes).
    pub fn restore(&mut self) -> Option<telemetry::Estimate> {
        let mut buf = [0u8; BUF];
        let item: Option<&[u8]> = block_on(self.map.fetch_item(&mut buf, &KEY)).ok()?;
        telemetry::decode_estimate(item?).ok()
    }

    /// Commits `e`; `true` once it is in flash.
    pub fn save(&mut self, e: &telemetry::Estimate) -> bool {
        let mut enc = [0u8; telemetry::MAX_ESTIMATE];
        let Ok(bytes) = telemetry::encode_estimate(e, &mut enc) else {
            return false;
        };
        let bytes: &[u8] = bytes;
        let mut buf = [0u8; BUF];
        block_on(self.map.store_item(&mut buf, &KEY, &bytes)).is_ok()
    }
}

/// Saves the report's estimate when it is worth keeping: `Converged`, or a tensor to be used
/// with its standard deviations ([`TensorReport::usable`](crate::app::TensorReport::usable):
/// a real throw's `ModelMismatch` with the residual's uncertainty), fed with samples not yet
/// saved.
pub struct SavePolicy {
    saved_fed: u32,
}

impl SavePolicy {
    /// Nothing saved yet in this boot.
    pub const fn new() -> Self {
        SavePolicy { saved_fed: 0 }
    }

    /// Whether the report's estimate should be committed now.
    pub fn due(&mut self, r: &crate::app::Report) -> bool {
        self.due_for(&r.tensor)
    }

    /// [`SavePolicy::due`] of the report's tensor estimate.
    fn due_for(&mut self, t: &crate::app::TensorReport) -> bool {
        let good = t.status == identifier_core::Status::Converged || t.usable;
        if good && t.fed != self.saved_fed {
            self.saved_fed = t.fed;
            true
        } else {
            false
        }
    }
}

impl Default for SavePolicy {
    fn default() -> Self {
        Self::new()
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing, clippy::panic)]
    extern crate std;
    use super::*;
    use embedded_storage_async::nor_flash::{
        ErrorType, NorFlashError, NorFlashErrorKind, ReadNorFlash,
    };
    use std::vec::Vec;

    const PAGE: usize = 128 * 1024;

    /// NOR flash in RAM: erase sets 0xFF, writes may only clear bits; `budget` bytes of writes
    /// left before the power fails (every later write or erase fails, as after a reset).
    struct RamFlash {
        mem: Vec<u8>,
        budget: Option<usize>,
    }

    #[derive(Debug)]
    struct PowerLost;
    impl NorFlashError for PowerLost {
        fn kind(&self) -> NorFlashErrorKind {
            NorFlashErrorKind::Other
        }
    }
    impl ErrorType for RamFlash {
        type Error = PowerLost;
    }
    impl ReadNorFlash for RamFlash {
        const READ_SIZE: usize = 1;
        async fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), PowerLost> {
            let o = offset as usize;
            bytes.copy_from_slice(&self.mem[o..o + bytes.len()]);
            Ok(())
        }
        fn capacity(&self) -> usize {
            self.mem.len()
        }
    }
    impl NorFlash for RamFlash {
        const WRITE_SIZE: usize = 4;
        const ERASE_SIZE: usize = PAGE;
        async fn erase(&mut self, from: u32, to: u32) -> Result<(), PowerLost> {
            if self.budget == Some(0) {
                return Err(PowerLost);
            }
            self.mem[from as usize..to as usize].fill(0xFF);
            Ok(())
        }
        async fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), PowerLost> {
            for (i, b) in bytes.iter().enumerate() {
                if let Some(n) = &mut self.budget {
                    if *n == 0 {
                        return Err(PowerLost);
                    }
                    *n -= 1;
                }
                let m = &mut self.mem[offset as usize + i];
                *m &= *b;
            }
            Ok(())
        }
    }

    fn estimate(k: u32) -> telemetry::Estimate {
        telemetry::Estimate {
            a_paper: [0.9, 0.26, -0.94],
            converged_paper: false,
            a_refined: [0.9, 0.26, k as f32],
            std_a: [1e-5; 3],
            converged_refined: true,
            consistency: 0.0,
            samples: k,
            tensor: Some(telemetry::Tensor {
                status: 7,
                a: Some([-0.51, 0.86, -0.62 - k as f32 * 1e-4]),
                std_a: Some([2e-3; 3]),
                tensor: Some([
                    [2.8e-5, 2.2e-6, 9.5e-6],
                    [2.2e-6, 9.6e-5, 3.1e-7],
                    [9.5e-6, 3.1e-7, 1.1e-4],
                ]),
                throws: k / 10,
                fed: 1000 * k,
                not_fed: 0,
                in_free_flight: false,
                uncertainty: 0,
                usable: true,
            }),
        }
    }

    fn fresh() -> Vec<u8> {
        std::vec![0xFF; 2 * PAGE]
    }

    fn store(mem: Vec<u8>, budget: Option<usize>) -> EstimateStore<RamFlash> {
        EstimateStore::new(RamFlash { mem, budget }, 0..(2 * PAGE) as u32).unwrap()
    }

    fn memory(s: EstimateStore<RamFlash>) -> Vec<u8> {
        // The map owns the flash: take it back.
        let EstimateStore { map } = s;
        map.destroy().0.mem
    }

    #[test]
    fn the_policy_saves_a_usable_estimate_once_per_new_samples() {
        use identifier_core::{Status, Uncertainty};
        let t = |status, usable, fed| crate::app::TensorReport {
            status,
            a: None,
            std_a: None,
            tensor: None,
            throws: 1,
            fed,
            not_fed: 0,
            in_free_flight: false,
            uncertainty: Uncertainty::Residual,
            usable,
        };
        let mut p = SavePolicy::new();
        assert!(!p.due_for(&t(Status::ModelMismatch, false, 100)));
        assert!(!p.due_for(&t(Status::Converging, false, 100)));
        assert!(p.due_for(&t(Status::ModelMismatch, true, 100)));
        assert!(!p.due_for(&t(Status::ModelMismatch, true, 100)));
        assert!(p.due_for(&t(Status::Converged, true, 200)));
    }

    #[test]
    fn empty_flash_restores_nothing_and_a_saved_estimate_comes_back() {
        let mut s = store(fresh(), None);
        assert_eq!(s.restore(), None);
        assert!(s.save(&estimate(1)));
        assert!(s.save(&estimate(2)));
        let mem = memory(s);
        // A reset: a new store on the same flash.
        let mut s = store(mem, None);
        assert_eq!(s.restore(), Some(estimate(2)));
    }

    #[test]
    fn a_reset_in_the_middle_of_a_campaign_loses_no_committed_estimate() {
        // A campaign of 2000 saves (both pages fill and are recycled several times), with the
        // power lost once after every possible number of written bytes within a window, at
        // several points of the campaign; after each loss the store must restore the last
        // estimate whose save returned true.
        let mut mem = fresh();
        let mut committed: Option<telemetry::Estimate> = None;
        let mut k = 0u32;
        let mut resets = 0;
        for round in 0..20 {
            // 100 clean saves.
            let mut s = store(mem, None);
            assert_eq!(s.restore(), committed, "round {round} start");
            for _ in 0..100 {
                k += 1;
                assert!(s.save(&estimate(k)));
                committed = Some(estimate(k));
            }
            mem = memory(s);
            // One save cut short after `cut` bytes, then a reset.
            let cut = (round * 37) % 200;
            let mut s = store(mem, Some(cut));
            k += 1;
            if s.save(&estimate(k)) {
                committed = Some(estimate(k));
            }
            mem = memory(s);
            resets += 1;
            let mut s = store(mem, None);
            assert_eq!(
                s.restore(),
                committed,
                "after reset {resets} (cut at {cut} bytes)"
            );
            mem = memory(s);
        }
        assert_eq!(resets, 20);
    }
}
