//! Fuzzes `trazo::fuzz::measured` (see src/fuzz.rs).
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| trazo::fuzz::measured(data));
