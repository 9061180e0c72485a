//! Link setup: embassy-stm32's `memory-x` feature writes the STM32F405RG's memory.x;
//! cortex-m-rt's `link.x` and defmt's `defmt.x` go to the binary.

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    if std::env::var("CARGO_CFG_TARGET_OS").as_deref() == Ok("none") {
        println!("cargo:rustc-link-arg-bins=--nmagic");
        println!("cargo:rustc-link-arg-bins=-Tlink.x");
        println!("cargo:rustc-link-arg-bins=-Tdefmt.x");
    }
}
