#![no_main]
//! `flame` input: see `ifslab_fuzz::check`.

libfuzzer_sys::fuzz_target!(|data: &[u8]| ifslab_fuzz::check("flame", data));
