#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| surfel_fuzz::load("obj", data));
