//! Fuzzes the OBJ loader: any input is loaded as `fuzz.obj` (in a folder
//! that does not exist) and must be refused with an error or give a scene
//! whose invariants hold; never a panic, a hang or unbounded memory.

#![no_main]

use libfuzzer_sys::fuzz_target;
use vis5d::scene::{LoadOptions, load_bytes};

fuzz_target!(|data: &[u8]| {
    if let Ok(scene) = load_bytes("/nonexistent/fuzz.obj", data, &LoadOptions::default()) {
        scene.validate().expect("an accepted scene keeps its invariants");
    }
});
