//! Problem construction, setup and solve from arbitrary bytes (see
//! `crates/gharial/tests/fuzz_entry/mod.rs` for the decoding and the contract).
#![no_main]

#[path = "../../crates/gharial/tests/fuzz_entry/mod.rs"]
mod fuzz_entry;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    fuzz_entry::run(data);
});
