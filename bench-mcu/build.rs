//! Memory layout of the STM32F405 (Cortex-M4F) of QEMU's `netduinoplus2` machine and of the
//! flight boards, and cortex-m-rt's linker script, for the thumb binary only. (The linker looks
//! in the workspace root first, where the firmware keeps a `memory.x` with the same layout.)

use std::{env, fs, path::PathBuf};

fn main() {
    let target = env::var("TARGET").unwrap_or_default();
    if !target.starts_with("thumb") {
        return;
    }
    let out = PathBuf::from(env::var("OUT_DIR").unwrap_or_else(|_| ".".into()));
    let memory = "MEMORY\n{\n  FLASH : ORIGIN = 0x08000000, LENGTH = 1024K\n  RAM : ORIGIN = 0x20000000, LENGTH = 128K\n}\n";
    if fs::write(out.join("memory.x"), memory).is_ok() {
        println!("cargo:rustc-link-search={}", out.display());
    }
    println!("cargo:rustc-link-arg-bins=-Tlink.x");
    println!("cargo:rerun-if-changed=build.rs");
}
