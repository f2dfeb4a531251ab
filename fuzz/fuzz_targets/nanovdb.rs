//! Fuzzes `trazo::fuzz::nanovdb` (see src/fuzz.rs).
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| trazo::fuzz::nanovdb(data));
