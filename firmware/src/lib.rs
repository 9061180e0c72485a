//! Flight firmware of the inertia-ratio identifier: gyro samples from an ICM-42688-P go one by
//! one into two identifiers of `identifier-core`, the paper's [`identifier_core::Identifier`]
//! and the refined [`identifier_core::Refined`] beside it (near the Cramer-Rao bound on noisy
//! gyros), and both estimates, the refined inertia ratios, the convergence status of each and
//! the counters go out as a defmt stream at 10 Hz.
//!
//! The library holds everything that is not tied to a board, generic over the driver's bus
//! interface, so the same code runs:
//! * on an STM32F405 flight controller (`src/bin/stm32f405.rs`, defmt over RTT, probe-rs);
//! * under QEMU (`src/bin/qemu.rs`), where the gyro is [`icm42688::sim::SimIcm42688`] fed
//!   from a recorded log read through semihosting;
//! * on the host, where `host-tests` runs [`SampleLoop`] over the same log and the same
//!   simulated part to produce the reference the QEMU run must reproduce bit for bit.
//!
//! Nothing here panics or allocates.
//!
//! # Defences
//!
//! [`SampleLoop`] guards the identifiers against a misbehaving sensor or bus (measured under
//! injected faults in `host-tests/tests/robustness_faults.rs`):
//! * a rate-jump check (plausibility gate, [`app::rate_check`]): a sample whose change from the
//!   last accepted one exceeds what the torque-free motion within the gyro's full scale allows
//!   ([`gate_rate_bound`]) is refused;
//! * dt from a [`SampleClock`] (a timer on the board), so lost samples lengthen the next step
//!   instead of shrinking the time base;
//! * re-initialisation of the sensor after consecutive bus errors, data-ready timeouts or
//!   invalid samples, after a wrong `WHO_AM_I`, or on stalled (frozen) data, and a periodic
//!   `WHO_AM_I` check;
//! * a counter for each, in the 10 Hz report.
//!
//! On the STM32F405 image the independent watchdog (IWDG) is fed once per loop iteration.
//! QEMU's `netduinoplus2` machine does not model the IWDG, so the QEMU image has no watchdog;
//! `checks/firmware-faults` exercises one on QEMU's `mps2-an386`, which models a CMSDK
//! watchdog.
//!
//! # Running
//!
//! * `scripts/run.sh`: build, simulate a spinning body, run under QEMU, show the estimates.
//! * `scripts/firmware-e2e.sh`: the same, checked against the host reference and the truth.
//! * `scripts/bench-firmware.sh`: instructions per step, flash/RAM, stack high-water.
//! * `cargo qemu -- <gyro log> [bus error every n]`: the QEMU image via its runner script.
//! * `cargo flash-board`: the STM32F405 image through `probe-rs run` (a probe attached).
//!
//! The binaries build only for `thumbv7em-none-eabihf` with their feature (`qemu` or
//! `stm32f405`); the library, with no feature, also builds and tests on the host.
#![no_std]
#![deny(missing_docs)]
#![deny(
    clippy::panic,
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing
)]

pub mod app;
pub mod bench;
pub mod log_format;
pub mod persist;
pub mod replay_format;
pub mod uplink;
// Stack painting needs `cortex-m`, which only the board features bring.
#[cfg(all(
    target_arch = "arm",
    target_os = "none",
    any(feature = "qemu", feature = "stm32f405")
))]
pub mod stack;

pub use app::{
    gate_rate_bound, identifier_settings, pipeline_settings, refined_settings, BoardInputs,
    InitError, LoopCounters, NoBoardInputs, NoDelay, Poll, Report, SampleClock, SampleInputs,
    SampleLoop, SampleRecord, SensorStatus, TensorReport,
};
