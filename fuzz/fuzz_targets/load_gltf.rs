//! Fuzzes the glTF and GLB loaders: an input starting with the GLB magic
//! is loaded as `fuzz.glb`, any other as `fuzz.gltf` (JSON), from a folder
//! that does not exist (so buffer files cannot be read: only embedded
//! `data:` buffers and the GLB chunk reach the accessors). It must be
//! refused with an error or give a scene whose invariants hold; never a
//! panic, a hang or unbounded memory.

#![no_main]

use libfuzzer_sys::fuzz_target;
use vis5d::scene::{LoadOptions, load_bytes};

fuzz_target!(|data: &[u8]| {
    let name = if data.starts_with(b"glTF") {
        "/nonexistent/fuzz.glb"
    } else {
        "/nonexistent/fuzz.gltf"
    };
    if let Ok(scene) = load_bytes(name, data, &LoadOptions::default()) {
        scene.validate().expect("an accepted scene keeps its invariants");
    }
});
