//! Fuzzes the `.v5d` decoder and the queries on whatever it accepts.
//!
//! Most inputs would stop at the checksum, so the target appends the
//! input's correct CRC-32 and the parser sees the rest (the checksum test
//! itself is covered by the unit tests). Whatever decodes is queried at
//! points taken from the input.

#![no_main]

use glam::Vec3;
use libfuzzer_sys::fuzz_target;
use vis5d::codec::crc32;
use vis5d::geom::Aabb;
use vis5d::query::{Pvs, View};

fuzz_target!(|data: &[u8]| {
    let mut bytes = data.to_vec();
    let crc = crc32(&bytes);
    bytes.extend_from_slice(&crc.to_le_bytes());
    let Ok(pvs) = Pvs::from_bytes(&bytes) else {
        return;
    };
    let mut out = pvs.new_set();
    let root = pvs.root_cell().space();
    for (k, chunk) in data.chunks(4).take(16).enumerate() {
        let f = chunk.iter().fold(0u32, |a, &b| a * 256 + b as u32) as f32 / u32::MAX as f32;
        let p = root.lerp(Vec3::splat(f));
        let dir = [Vec3::X, -Vec3::Z, Vec3::new(f - 0.5, 0.3, -f)][k % 3];
        let _ = pvs.query_view(&View::square(p, dir, 10.0 + 160.0 * f), &mut out);
        let _ = pvs.query_range(&Aabb::new(p, p), (f * 6.0 - 3.0, -1.0), (0.0, f * 3.0), &mut out);
        // With slices (version 4): the triangle ranges too.
        let _ = pvs.query_view_triangles(&View::square(p, dir, 90.0), &mut out);
        let _ = pvs.leaf_set([p.x, p.y, p.z, f, f], &mut out);
    }
});
