//! Slices in `.v5d` files (papers/004 sec. 3, format version 4): a tree's
//! leaves carry the slices the oracle proved hidden, the file round-trips
//! them and refuses them damaged, and `Pvs` answers triangle ranges that
//! never leave out a triangle a ray from the query's positions hits.

use glam::Vec3;
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64;
use vis5d::codec::{ReadLimits, V5dFile, crc32, read_file, write_file};
use vis5d::conservative::BakeParams;
use vis5d::geom::Aabb;
use vis5d::geom::cell::direction_to_angles;
use vis5d::oracle::{Oracle, OracleParams, Rasteriser};
use vis5d::query::Pvs;
use vis5d::random::{uniform_direction, uniform_point};
use vis5d::scene::Scene;
use vis5d::slices::{SlicedScene, TreeSlices, leaf_slices};
use vis5d::trace::{Ray, Tracer};

use crate::shrink::terrain_town;
use crate::{text, vis5d};

/// The streets' box of positions in [`terrain_town`]: 0.5 to 4 m up.
fn street_box() -> Aabb {
    Aabb::new(Vec3::new(0.0, 0.0, 0.5), Vec3::new(128.0, 128.0, 4.0))
}

/// The terrain town baked conservatively over [`street_box`], with its
/// leaves' slices (8 an axis), as a file.
fn baked() -> (Scene, V5dFile) {
    let scene = terrain_town();
    let oracle = Oracle::new(&scene, OracleParams::default(), Rasteriser::cpu()).unwrap();
    let params = BakeParams {
        max_depth: 6,
        view_box: Some(street_box()),
        ..BakeParams::default()
    };
    let (tree, _) = vis5d::conservative::bake(&oracle, &params, &|_| {}).unwrap();
    let sliced = SlicedScene::new(&scene, 8).unwrap();
    let leaves = leaf_slices(&tree, &oracle, &sliced, true, &|_, _| {});
    let text = params.to_text(&oracle);
    let mut file = vis5d::builder::file_with_params(&scene, tree, text, None);
    file.slices = Some(TreeSlices { sliced, leaves });
    (scene, file)
}

#[test]
fn queries_never_cull_a_triangle_a_ray_hits_and_cull_much() {
    let (scene, file) = baked();
    let bytes = write_file(&file);
    let back = read_file(&bytes, ReadLimits::default()).unwrap();
    assert_eq!(back.tree, file.tree);
    assert!(back.slices == file.slices, "the slices round-trip");
    let slices = file.slices.as_ref().unwrap();
    let entries: usize = slices.leaves.iter().map(Vec::len).sum();
    assert!(entries > 0, "no leaf has slices");
    let pvs = Pvs::from_bytes(&bytes).unwrap();
    assert!(pvs.slices().is_some());
    let tracer = Tracer::new(&scene);
    let mut rng = Pcg64::seed_from_u64(0x51ce5);
    let street = street_box();
    let mut set = pvs.new_set();
    let (mut drawn, mut whole, mut hits) = (0u64, 0u64, 0);
    for _ in 0..40 {
        // A small box of positions and a narrow range of directions
        // around a random ray's.
        let c = uniform_point(&mut rng, &street);
        let positions = Aabb::new((c - 0.25).max(street.min), (c + 0.25).min(street.max));
        let d = uniform_direction(&mut rng);
        let (t, p) = direction_to_angles(d);
        let (theta, phi) = (
            (t - 0.1, t + 0.1),
            ((p - 0.1).max(0.0), (p + 0.1).min(std::f32::consts::PI)),
        );
        let answer = pvs
            .query_range_triangles(&positions, theta, phi, &mut set)
            .unwrap();
        drawn += answer.iter().map(|a| a.count()).sum::<u64>();
        whole += set
            .iter()
            .map(|o| scene.objects()[o].triangle_count() as u64)
            .sum::<u64>();
        // Rays from the positions into the directions: every triangle hit
        // is drawn.
        let rays: Vec<Ray> = (0..2000)
            .map(|_| {
                let o = uniform_point(&mut rng, &positions);
                let theta = rng.random_range(theta.0..theta.1);
                let phi = rng.random_range(phi.0..phi.1);
                Ray::new(o, vis5d::geom::cell::angles_to_direction(theta, phi))
            })
            .collect();
        for h in tracer.closest_hits(&rays).into_iter().flatten() {
            hits += 1;
            let o = h.object as usize;
            let t = h.triangle - scene.objects()[o].triangles.start;
            assert!(set.contains(o), "object {o} hit, not in the set");
            let a = answer.iter().find(|a| a.object as usize == o).unwrap();
            assert!(
                a.ranges.iter().any(|r| r.contains(&t)),
                "triangle {t} of object {o} hit from {positions:?}, not in {:?}",
                a.ranges
            );
        }
    }
    eprintln!("{hits} hits; {drawn} of {whole} triangles drawn");
    assert!(hits > 10_000, "{hits}");
    // The terrain's pieces behind the blocks from the leaves (16 x 16 m
    // boxes of positions at this depth): less is drawn (80.7% at this
    // seed).
    assert!((drawn as f64) < 0.9 * whole as f64, "{drawn} of {whole}");
}

/// The offset of the slices section (after its length) in `file`'s bytes.
fn section(file: &V5dFile) -> usize {
    let mut plain = file.clone();
    plain.slices = None;
    // A file without slices ends: ..., length 0, checksum.
    write_file(&plain).len() - 4
}

/// `bytes` with the checksum made right again.
fn resealed(mut bytes: Vec<u8>) -> Vec<u8> {
    let n = bytes.len() - 4;
    let crc = crc32(&bytes[..n]);
    bytes[n..].copy_from_slice(&crc.to_le_bytes());
    bytes
}

#[test]
fn damaged_slices_are_refused_by_name() {
    let (_, file) = baked();
    let bytes = write_file(&file);
    let at = section(&file);
    let refuse = |bytes: Vec<u8>, says: &str| {
        let b = resealed(bytes);
        let e = read_file(&b, ReadLimits::default()).unwrap_err();
        assert!(e.to_string().contains(says), "{e} (wanted {says:?})");
        assert!(Pvs::from_bytes(&b).is_err());
    };
    // The slice count.
    for n in [0u8, 128, 255] {
        let mut b = bytes.clone();
        b[at] = n;
        refuse(b, "slices an axis");
    }
    // A leaf index past its piece's slices: the last bytes of the section
    // are the last leaf's last index (its z).
    let last_leaf_has_slices = !file
        .slices
        .as_ref()
        .unwrap()
        .leaves
        .last()
        .unwrap()
        .is_empty();
    if last_leaf_has_slices {
        let mut b = bytes.clone();
        let z = b.len() - 5;
        b[z] = 100;
        refuse(b, "past its");
    }
    // Cut short: the section's length says more than follows.
    let mut b = bytes.clone();
    let len_at = at - 4;
    let len = u32::from_le_bytes(b[len_at..at].try_into().unwrap());
    b[len_at..at].copy_from_slice(&(len + 1).to_le_bytes());
    refuse(b, "the slices take");
    // A triangle's slice range upside down (the first triangle of the
    // first object: after the count, the piece count and 27 bytes).
    let pieces = bytes[at + 1] as usize;
    let first_triangle = at + 2 + 27 * pieces + usize::from(pieces > 1);
    let mut b = bytes.clone();
    b[first_triangle] = 7;
    b[first_triangle + 3] = 0;
    refuse(b, "has slices");
    // Every single-byte change is refused or read as some file whose
    // queries answer: never a panic.
    let view = vis5d::query::View::square(Vec3::new(50.0, 3.0, 2.0), Vec3::Y, 90.0);
    for k in (at..bytes.len() - 4).step_by(13) {
        let mut b = bytes.clone();
        b[k] ^= 0x5a;
        let b = resealed(b);
        let _ = read_file(&b, ReadLimits::default());
        if let Ok(pvs) = Pvs::from_bytes(&b) {
            let mut set = pvs.new_set();
            let drawn = pvs.query_view_triangles(&view, &mut set).unwrap();
            assert_eq!(drawn.len(), set.count());
        }
    }
}

#[test]
fn build_and_query_with_slices_on_the_command_line() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("apartment.v5d");
    let out = out.to_str().unwrap();
    let built = vis5d(&[
        "build",
        "scenes/apartment.obj",
        "--conservative",
        "--max-depth",
        "4",
        "--slices",
        "8",
        "-o",
        out,
        "--json",
    ]);
    assert!(built.status.success(), "{}", text(&built.stderr));
    let j: serde_json::Value = serde_json::from_slice(&built.stdout).unwrap();
    assert_eq!(j["slices"]["slices"], 8, "{j}");
    assert!(j["slices"]["oracle_cells"].as_u64().unwrap() > 0, "{j}");
    // The same bytes on one thread.
    let one = dir.path().join("one.v5d");
    let one = one.to_str().unwrap();
    let again = vis5d(&[
        "build",
        "scenes/apartment.obj",
        "--conservative",
        "--max-depth",
        "4",
        "--slices",
        "8",
        "--threads",
        "1",
        "-o",
        one,
    ]);
    assert!(again.status.success(), "{}", text(&again.stderr));
    assert!(
        std::fs::read(out).unwrap() == std::fs::read(one).unwrap(),
        "the file depends on the thread count"
    );
    let stat = vis5d(&["stat", out, "--json"]);
    let s: serde_json::Value = serde_json::from_slice(&stat.stdout).unwrap();
    assert_eq!(s["version"], vis5d::codec::VERSION);
    assert_eq!(s["slices"]["slices"], 8, "{s}");
    let q = vis5d(&[
        "query",
        out,
        "--pos",
        "2,2,1.5",
        "--dir",
        "1,0,0",
        "--triangles",
        "--json",
    ]);
    assert!(q.status.success(), "{}", text(&q.stderr));
    let rows: serde_json::Value = serde_json::from_slice(&q.stdout).unwrap();
    let rows = rows.as_array().unwrap();
    assert!(!rows.is_empty());
    for r in rows {
        let n: u64 = r["ranges"]
            .as_array()
            .unwrap()
            .iter()
            .map(|p| p[1].as_u64().unwrap() - p[0].as_u64().unwrap())
            .sum();
        assert_eq!(n, r["triangles"].as_u64().unwrap(), "{r}");
    }
    // Text, and a file without slices says so.
    let plain = dir.path().join("plain.v5d");
    let plain = plain.to_str().unwrap();
    let built = vis5d(&[
        "build",
        "scenes/apartment.obj",
        "--conservative",
        "--max-depth",
        "2",
        "-o",
        plain,
    ]);
    assert!(built.status.success(), "{}", text(&built.stderr));
    let q = vis5d(&[
        "query",
        plain,
        "--pos",
        "2,2,1.5",
        "--dir",
        "1,0,0",
        "--triangles",
    ]);
    assert!(
        text(&q.stdout).contains("has no slices"),
        "{}",
        text(&q.stdout)
    );
    // Out of range.
    for bad in ["128", "-1", "x"] {
        let flag = format!("--slices={bad}");
        let r = vis5d(&["build", "scenes/apartment.obj", &flag, "--dry-run"]);
        assert!(!r.status.success());
        assert!(text(&r.stderr).contains("--slices"), "{}", text(&r.stderr));
    }
}
