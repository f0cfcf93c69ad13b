#![no_main]
//! `image` input: see `ifslab_fuzz::check`.

libfuzzer_sys::fuzz_target!(|data: &[u8]| ifslab_fuzz::check("image", data));
