//! Fuzz target of the SRDF reader: see `gharial_multibody_fuzz::srdf`.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    gharial_multibody_fuzz::srdf(data);
});
