//! Fuzzes `trazo::fuzz::mitsuba` (see src/fuzz.rs).
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| trazo::fuzz::mitsuba(data));
