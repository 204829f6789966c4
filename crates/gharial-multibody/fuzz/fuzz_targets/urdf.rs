//! Fuzz target of the URDF reader: see `gharial_multibody_fuzz::urdf`.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    gharial_multibody_fuzz::urdf(data);
});
