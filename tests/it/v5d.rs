//! The `.v5d` file and the runtime queries: round trips, queries against
//! brute force and against rendered rays, the fingerprint, bad files.

use std::sync::OnceLock;

use glam::Vec3;
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64;
use vis5d::bitset::ObjectSet;
use vis5d::builder::{BuildParams, build, to_file};
use vis5d::codec::{self, CodecError, Coding, ReadLimits};
use vis5d::geom::Aabb;
use vis5d::geom::cell::{Cell, DIMS, direction_to_angles};
use vis5d::query::{Answer, Delta, Pvs, SetSizeError, View};
use vis5d::random::{uniform_direction, uniform_point};
use vis5d::render::Camera;
use vis5d::scene::{self, Scene};
use vis5d::trace::Tracer;
use vis5d::tree::VisTree;

/// The committed apartment, its tracer and its default tree, built once.
fn apartment() -> &'static (Scene, Tracer, VisTree) {
    static CELL: OnceLock<(Scene, Tracer, VisTree)> = OnceLock::new();
    CELL.get_or_init(|| {
        let s = scene::load(crate::committed("apartment.obj")).unwrap();
        let t = Tracer::new(&s);
        let (tree, _) = build(&s, &t, &BuildParams::default(), &|_| {}).unwrap();
        (s, t, tree)
    })
}

fn file_bytes(coding: Option<Coding>) -> Vec<u8> {
    let (s, _, tree) = apartment();
    codec::write_file(&to_file(s, tree.clone(), &BuildParams::default(), coding))
}

#[test]
fn files_round_trip_in_every_coding() {
    let (s, _, tree) = apartment();
    let mut sizes = Vec::new();
    for coding in Coding::ALL {
        let bytes = file_bytes(Some(coding));
        let f = codec::read_file(&bytes, ReadLimits::default()).unwrap();
        assert_eq!(&f.tree, tree, "{coding}");
        assert_eq!(f.coding, coding);
        assert_eq!(f.fingerprint, s.fingerprint());
        assert_eq!(f.objects.len(), s.objects().len());
        assert_eq!(f.objects[3].name, s.objects()[3].name);
        assert_eq!(
            f.objects[3].triangles as usize,
            s.objects()[3].triangle_count()
        );
        assert!(f.params.contains("s_thresh=0.01\n"), "{}", f.params);
        sizes.push(bytes.len());
    }
    // On this occluded scene each coding is smaller than the one before,
    // and the default is the smallest.
    assert!(sizes[0] > sizes[1] && sizes[1] > sizes[2], "{sizes:?}");
    assert_eq!(file_bytes(None).len(), sizes[2]);
    // The same inputs give the same bytes.
    assert_eq!(file_bytes(None), file_bytes(None));
}

#[test]
fn the_leaf_found_by_the_query_holds_the_builders_set() {
    let (_, _, tree) = apartment();
    let pvs = Pvs::from_bytes(&file_bytes(None)).unwrap();
    let mut out = pvs.new_set();
    let root = tree.root_cell();
    let mut rng = Pcg64::seed_from_u64(11);
    let cells: std::collections::HashMap<usize, Cell> =
        tree.leaves().iter().map(|l| (l.node, l.cell)).collect();
    let mut ranks = std::collections::HashMap::new();
    for _ in 0..20_000 {
        let p: [f32; DIMS] = root.sample([
            rng.random(),
            rng.random(),
            rng.random(),
            rng.random(),
            rng.random(),
        ]);
        let leaf = tree.locate(p);
        assert_eq!(pvs.leaf_set(p, &mut out), Ok(Answer::Tree));
        assert_eq!(out, tree.nodes()[leaf].set);
        // `leaf_at` names the same leaf: its cell, and one rank per leaf.
        let (rank, cell) = pvs.leaf_at(p).unwrap();
        assert_eq!(cell, cells[&leaf], "{p:?}");
        assert_eq!(*ranks.entry(rank).or_insert(leaf), leaf, "{p:?}");
    }
    assert!(ranks.len() > 100, "{}", ranks.len());
    // Outside the view box, or a NaN: no leaf.
    let mut p = root.sample([0.5; DIMS]);
    assert!(pvs.leaf_at(p).is_some());
    p[0] = root.hi[0] + 1.0;
    assert_eq!(pvs.leaf_at(p), None);
    p[0] = f32::NAN;
    assert_eq!(pvs.leaf_at(p), None);
}

/// Whether the closed range meets the half-open cell (the query's rule).
fn meets(range: &Cell, cell: &Cell, root: &Cell) -> bool {
    (0..DIMS).all(|d| {
        let below_hi = if cell.hi[d] == root.hi[d] {
            range.lo[d] <= cell.hi[d]
        } else {
            range.lo[d] < cell.hi[d]
        };
        below_hi && range.hi[d] >= cell.lo[d]
    })
}

#[test]
fn range_queries_equal_a_linear_scan_of_the_leaves() {
    let (_, _, tree) = apartment();
    let pvs = Pvs::from_bytes(&file_bytes(Some(Coding::Parent))).unwrap();
    let root = tree.root_cell();
    let leaves = tree.leaves();
    let mut rng = Pcg64::seed_from_u64(12);
    let mut out = pvs.new_set();
    for k in 0..2_000 {
        let a = root.sample([
            rng.random(),
            rng.random(),
            rng.random(),
            rng.random(),
            rng.random(),
        ]);
        let b = root.sample([
            rng.random(),
            rng.random(),
            rng.random(),
            rng.random(),
            rng.random(),
        ]);
        let mut range = Cell { lo: a, hi: a };
        for d in 0..DIMS {
            // Small ranges mostly, some large; some exactly on split planes.
            let f = if k % 4 == 0 { 1.0 } else { 0.05 };
            range.lo[d] = a[d].min(a[d] + (b[d] - a[d]) * f);
            range.hi[d] = a[d].max(a[d] + (b[d] - a[d]) * f);
        }
        if k % 7 == 0 {
            let l = leaves[k % leaves.len()].cell;
            range = Cell { lo: l.lo, hi: l.lo };
        }
        let positions = Aabb::new(
            Vec3::new(range.lo[0], range.lo[1], range.lo[2]),
            Vec3::new(range.hi[0], range.hi[1], range.hi[2]),
        );
        pvs.query_range(
            &positions,
            (range.lo[3], range.hi[3]),
            (range.lo[4], range.hi[4]),
            &mut out,
        )
        .unwrap();
        let mut want = ObjectSet::new(tree.object_count());
        for l in leaves.iter().filter(|l| meets(&range, &l.cell, &root)) {
            want.union_with(&tree.nodes()[l.node].set);
        }
        assert_eq!(out, want, "range {range:?}");
    }
}

#[test]
fn a_view_query_holds_every_pixel_rays_leaf_set() {
    let (s, tracer, tree) = apartment();
    let pvs = Pvs::from_bytes(&file_bytes(None)).unwrap();
    let space = tree.root_cell().space();
    let mut rng = Pcg64::seed_from_u64(13);
    let mut out = pvs.new_set();
    let mut sizes = 0;
    for k in 0..150 {
        let eye = uniform_point(&mut rng, &space);
        let mut dir = uniform_direction(&mut rng);
        if k % 10 == 0 {
            dir = [-Vec3::X, Vec3::Z, -Vec3::Z][k / 10 % 3]; // wrap-around and the poles
        }
        let fov = [60.0, 90.0, 120.0][k % 3];
        let view = View::square(eye, dir, fov);
        pvs.query_view(&view, &mut out).unwrap();
        sizes += out.count();
        // The answer is culled to the frustum: every pixel ray's leaf set,
        // less the objects whose bounds lie outside the frustum, is in it,
        // and so is every object a pixel ray hits.
        let mut in_frustum = pvs.new_set();
        vis5d::report::frustum_set(s, &view, &mut in_frustum);
        let camera = Camera::new(&view, 32, 32).expect("a valid view");
        let rays = camera.pixel_rays();
        for (r, hit) in rays.iter().zip(tracer.closest_hits(&rays)) {
            let (t, p) = direction_to_angles(r.dir);
            let leaf = tree.locate([eye.x, eye.y, eye.z, t, p]);
            let mut want = tree.nodes()[leaf].set.clone();
            want.intersect_with(&in_frustum);
            assert!(
                want.is_subset(&out),
                "view {k}: a pixel's leaf set is not in the view's answer"
            );
            if let Some(h) = hit {
                assert!(
                    !tree.nodes()[leaf].set.contains(h.object as usize)
                        || out.contains(h.object as usize),
                    "view {k}: object {} is hit, in its leaf, and culled",
                    h.object
                );
            }
        }
    }
    // And it culls: on average well under the whole scene.
    let mean = sizes as f64 / 150.0;
    assert!(mean < 0.6 * s.objects().len() as f64, "mean answer {mean}");
}

#[test]
fn odd_ranges_are_answered_safely() {
    let pvs = Pvs::from_bytes(&file_bytes(None)).unwrap();
    let mut out = pvs.new_set();
    // Outside the view box: every object the frustum holds (looking back
    // at the whole apartment), none of those behind the eye, and it says
    // so.
    let back = View::square(Vec3::new(100.0, 2.6, 1.3), -Vec3::X, 90.0);
    assert_eq!(pvs.query_view(&back, &mut out), Ok(Answer::Everything));
    assert_eq!(out.count(), pvs.object_count());
    let away = View::square(Vec3::new(100.0, 2.6, 1.3), Vec3::X, 90.0);
    assert_eq!(pvs.query_view(&away, &mut out), Ok(Answer::Everything));
    assert_eq!(out.count(), 0);
    // A NaN anywhere: everything; an empty range: nothing.
    let b = pvs.root_cell().space();
    assert_eq!(pvs.view_box(), b);
    let c = Aabb::new(b.center(), b.center());
    let nan = pvs.query_range(&c, (0.0, 1.0), (f32::NAN, 1.0), &mut out);
    assert_eq!(nan, Ok(Answer::Everything));
    assert_eq!(out.count(), pvs.object_count());
    let empty = pvs.query_range(&c, (0.0, 1.0), (2.0, 1.0), &mut out);
    assert_eq!(empty, Ok(Answer::Tree));
    assert_eq!(out.count(), 0);
    let inverted = Aabb::new(b.center() + Vec3::X * 0.1, b.center());
    pvs.query_range(&inverted, (0.0, 1.0), (0.0, 1.0), &mut out)
        .unwrap();
    assert_eq!(out.count(), 0);
    // Angles beyond the root are clipped: the same as the full range.
    let mut full = pvs.new_set();
    let pi = std::f32::consts::PI;
    pvs.query_range(&c, (-4.0, 4.0), (-1.0, 4.0), &mut out)
        .unwrap();
    let inside = pvs.query_range(&c, (-pi, pi), (0.0, pi), &mut full);
    assert_eq!(inside, Ok(Answer::Tree));
    assert_eq!(out, full);
    // The leaf of a point outside the view box (or of a NaN): every
    // object, and it says so; no record.
    let n = pvs.object_count();
    for p in [
        [100.0, 2.6, 1.3, 0.0, 1.0],
        [f32::NAN, 2.6, 1.3, 0.0, 1.0],
        [b.center().x, b.center().y, b.center().z, 0.0, 4.0],
    ] {
        let mut all = pvs.new_set();
        assert_eq!(pvs.leaf_set(p, &mut all), Ok(Answer::Everything), "{p:?}");
        assert_eq!(all.count(), n);
    }
    let centre = [b.center().x, b.center().y, b.center().z, 0.0, 1.0];
    assert_eq!(pvs.leaf_set(centre, &mut pvs.new_set()), Ok(Answer::Tree));
    assert!(pvs.leaf_set(centre, &mut ObjectSet::new(n + 1)).is_err());
    // A set of another size: an error, the set untouched; never a
    // truncated answer or a panic.
    let inside_view = View::square(b.center(), Vec3::X, 90.0);
    for size in [0, n - 1, n + 1, n + 64] {
        let mut wrong = ObjectSet::new(size);
        if size > 0 {
            wrong.insert(0);
        }
        let expected = Err(SetSizeError {
            got: size,
            expected: n,
        });
        assert_eq!(pvs.query_view(&inside_view, &mut wrong), expected);
        assert_eq!(pvs.query_view(&back, &mut wrong), expected);
        assert_eq!(
            pvs.query_range(&c, (-pi, pi), (0.0, pi), &mut wrong),
            expected
        );
        assert_eq!(
            pvs.query_view_triangles(&inside_view, &mut wrong).err(),
            expected.err()
        );
        assert_eq!(wrong.count(), usize::from(size > 0));
    }
}

#[test]
fn the_fingerprint_check_fires_when_the_scene_changes() {
    let (s, _, _) = apartment();
    let pvs = Pvs::from_bytes(&file_bytes(None)).unwrap();
    pvs.check_fingerprint(s.fingerprint()).unwrap();
    // Another layout of the same kind of scene, and one moved vertex.
    let other =
        vis5d::scene::procedural::generate(vis5d::scene::procedural::SceneKind::Apartment, 2, 1);
    let e = pvs.check_fingerprint(other.fingerprint()).unwrap_err();
    assert!(
        e.to_string().contains("another version of the scene"),
        "{e}"
    );
    let mut text = std::fs::read_to_string(crate::committed("apartment.obj")).unwrap();
    let at = text.find("\nv ").unwrap() + 3;
    text.insert(at, '1');
    let moved = scene::load_obj_bytes("moved.obj", text.as_bytes()).unwrap();
    assert!(pvs.check_fingerprint(moved.fingerprint()).is_err());
}

#[test]
fn damaged_files_are_refused_with_a_reason() {
    let good = file_bytes(None);
    let read = |b: &[u8]| codec::read_file(b, ReadLimits::default());
    assert_eq!(
        read(b"hello world, this is not a tree").unwrap_err(),
        CodecError::NotV5d
    );
    assert_eq!(read(&[]).unwrap_err(), CodecError::NotV5d);
    // Truncated anywhere.
    for len in (0..good.len()).step_by(97).chain([8, 20, good.len() - 1]) {
        let e = read(&good[..len]).unwrap_err();
        assert!(
            matches!(
                e,
                CodecError::Truncated(_) | CodecError::NotV5d | CodecError::Checksum { .. }
            ),
            "{len}: {e}"
        );
    }
    // A flipped bit anywhere past the magic and version: the checksum.
    for k in (10 * 8..good.len() * 8).step_by(331) {
        let mut b = good.clone();
        b[k / 8] ^= 1 << (k % 8);
        assert!(
            matches!(read(&b).unwrap_err(), CodecError::Checksum { .. }),
            "bit {k}"
        );
    }
    // Another version.
    let mut b = good.clone();
    b[8] = 9;
    assert_eq!(read(&b).unwrap_err(), CodecError::Version(9));
    // Fields that lie, with a recomputed checksum.
    let patch = |offset: usize, bytes: &[u8]| {
        let mut b = good.clone();
        b[offset..offset + bytes.len()].copy_from_slice(bytes);
        let n = b.len() - 4;
        let crc = codec::crc32(&b[..n]);
        b[n..].copy_from_slice(&crc.to_le_bytes());
        b
    };
    let cases: [(usize, Vec<u8>, &str); 8] = [
        (10, vec![7], "unknown coding"),
        (11, vec![0], "grid bits"),
        (12, u32::MAX.to_le_bytes().to_vec(), "objects cannot fit"),
        (16, 5u32.to_le_bytes().to_vec(), "binary tree"),
        (
            16,
            (2 * 400_000_001u32 - 1).to_le_bytes().to_vec(),
            "binary tree",
        ),
        (32, f32::NAN.to_le_bytes().to_vec(), "root cell"),
        (80, f64::INFINITY.to_le_bytes().to_vec(), "frame origin"),
        // Version 1 has no frame: its parameters start where the origin is.
        (8, 1u16.to_le_bytes().to_vec(), ""),
    ];
    for (offset, bytes, want) in cases {
        let e = read(&patch(offset, &bytes)).unwrap_err();
        assert!(e.to_string().contains(want), "offset {offset}: {e}");
    }
    // A huge tree claimed by a small file is refused before allocating.
    let mut b = patch(16, &(2 * 300_000_000u32 - 1).to_le_bytes());
    b[20..24].copy_from_slice(&300_000_000u32.to_le_bytes());
    let n = b.len() - 4;
    let crc = codec::crc32(&b[..n]);
    b[n..].copy_from_slice(&crc.to_le_bytes());
    let small = ReadLimits {
        max_decoded_bytes: 1 << 20,
        ..ReadLimits::default()
    };
    assert!(matches!(
        codec::read_file(&b, small).unwrap_err(),
        CodecError::TooLarge(_)
    ));
    // A file whose tree decodes to 0.7 GiB: under the decoder's 1 GiB
    // budget, but a loaded Pvs holds the tree and a flat copy at once, so
    // it refuses more than half (a crafted 6 MB file decoded to 2 GB).
    let mut b = patch(16, &(2 * 4_000_000u32 - 1).to_le_bytes());
    b[20..24].copy_from_slice(&4_000_000u32.to_le_bytes());
    let n = b.len() - 4;
    let crc = codec::crc32(&b[..n]);
    b[n..].copy_from_slice(&crc.to_le_bytes());
    let e = codec::read_file(&b, ReadLimits::default()).unwrap_err();
    assert!(!matches!(e, CodecError::TooLarge(_)), "{e}");
    assert!(matches!(
        Pvs::from_bytes(&b).unwrap_err(),
        CodecError::TooLarge(_)
    ));
}

#[test]
fn regression_corpus_decodes_without_panicking() {
    // Inputs kept from the fuzzer's corpus and its crashes (fuzz/README.md):
    // one per distinct outcome, each named after it. Each must be refused
    // or decoded, never panic, loop or allocate without bound. Files hold
    // the input without its checksum.
    let dir = crate::root().join("tests/v5d_corpus");
    let mut n = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        let mut bytes = std::fs::read(&path).unwrap();
        // As the fuzz target: the input, then its correct checksum.
        let _ = Pvs::from_bytes(&bytes);
        let crc = codec::crc32(&bytes);
        bytes.extend_from_slice(&crc.to_le_bytes());
        let decoded = Pvs::from_bytes(&bytes);
        if let Ok(pvs) = &decoded {
            let mut out = pvs.new_set();
            let c = pvs.root_cell().space().center();
            pvs.query_view(&View::square(c, Vec3::X, 90.0), &mut out)
                .unwrap();
        }
        // Files are named after what reading them must give.
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        assert_eq!(
            decoded.is_ok(),
            name.starts_with("ok_"),
            "{name}: {:?}",
            decoded.err()
        );
        n += 1;
    }
    assert!(n > 0, "no corpus in {}", dir.display());
}

/// Culling keeps every point a renderer's pixel rays reach, also where the
/// renderer's f32 frame is off the exact one: a review found `Camera`
/// rolled by 6e-5 rad with `up` 1e-3 rad from `dir`, and `query_view`
/// culled an object a 160-degree-wide view's edge pixel hit.
#[test]
fn culling_keeps_what_a_renderers_edge_pixels_reach() {
    use vis5d::query::Frustum;
    let eye = Vec3::new(1.0, 2.0, 1.5);
    let dir = Vec3::new(0.3, -0.8, 0.2).normalize();
    let side = dir.any_orthonormal_vector();
    let mut checked = 0;
    for angle in [1.001e-3f32, 3e-3, 1.1e-2, 0.02, 0.3, 1.5] {
        let up = (dir * angle.cos() + side * angle.sin()).normalize();
        for (fx, fy) in [
            (30.0f32, 160.0f32),
            (160.0, 30.0),
            (90.0, 90.0),
            (1.0, 169.0),
            (0.01, 0.01),
        ] {
            let mut view = View::square(eye, dir, fx);
            view.up = up;
            view.fov_y = fy.to_radians();
            let frustum = Frustum::new(&view, &Aabb::new(eye, eye));
            let Some(camera) = Camera::new(&view, 3840, 2160) else {
                continue;
            };
            for (x, y) in [
                (0.0, 0.0),
                (3840.0, 0.0),
                (0.0, 2160.0),
                (3840.0, 2160.0),
                (1920.0, 0.0),
                (0.0, 1080.0),
            ] {
                let r = camera.ray_through(x, y);
                for t in [0.01f32, 1.0, 30.0, 1000.0] {
                    let p = r.origin + r.dir * t;
                    assert!(
                        frustum.may_see(&Aabb::new(p, p)),
                        "up {angle} rad from dir, fov {fx}x{fy}: the point at t = {t} of pixel ({x}, {y}) is culled"
                    );
                    checked += 1;
                }
            }
        }
    }
    assert!(checked > 500, "{checked}");
}

/// Version 3 keeps a record per leaf (how sure its set is): built trees
/// have one, it survives the file and `Pvs` answers it for the leaf a point
/// is in; a version 2 file (no records) still reads, without them; records
/// that lie are refused.
#[test]
fn leaf_records_round_trip_and_lies_are_refused() {
    let (s, _, tree) = apartment();
    let records = tree.leaf_records().expect("a built tree has records");
    assert_eq!(records.len(), tree.leaf_count());
    let sprt = BuildParams::default().sprt.misses_to_invisible();
    for r in records {
        // A rejection rests on at least the SPRT's run of misses.
        assert_eq!(r.rejected == 0, r.fewest_rays == 0, "{r:?}");
        assert!(r.rejected == 0 || r.fewest_rays >= sprt, "{r:?}");
    }
    assert!(records.iter().any(|r| r.rejected > 0));
    let risk = records
        .iter()
        .map(|r| r.largest_missed_fraction(0.95))
        .fold(0.0, f64::max);
    assert!(risk > 0.0 && risk < 0.05, "{risk}");
    let good = file_bytes(None);
    let f = codec::read_file(&good, ReadLimits::default()).unwrap();
    assert_eq!(f.tree.leaf_records(), Some(records));
    // The runtime does not hold them (no query needs them).
    let pvs = Pvs::from_bytes(&good).unwrap();
    // The same file as version 2: the records' length field and the
    // records go (and version 4's slices' length), the version says 2.
    // The records and their u32 length come before the slices' length (0
    // here) and the checksum: three LEB128 numbers a leaf.
    let varint_len = |v: u32| (32 - v.leading_zeros()).div_ceil(7).max(1) as usize;
    let records_len = 4 + records
        .iter()
        .map(|r| varint_len(r.rejected) + varint_len(r.fewest_rays) + varint_len(r.undecided))
        .sum::<usize>();
    assert_eq!(good[good.len() - 8..good.len() - 4], [0; 4], "no slices");
    // Before version 5 no up axis (the byte after the frame origin, 2:
    // +z) and no id lengths in the object table (0 here: every id is its
    // name).
    let pre5 = before_version_5(&good[..good.len() - 4], pvs.object_count());
    let mut v4 = pre5.clone();
    v4[8..10].copy_from_slice(&4u16.to_le_bytes());
    let crc = codec::crc32(&v4);
    v4.extend_from_slice(&crc.to_le_bytes());
    let old4 = codec::read_file(&v4, ReadLimits::default()).unwrap();
    assert_eq!(
        old4,
        codec::read_file(&good, ReadLimits::default()).unwrap()
    );
    let mut v2 = pre5[..pre5.len() - 4 - records_len].to_vec();
    v2[8..10].copy_from_slice(&2u16.to_le_bytes());
    let crc = codec::crc32(&v2);
    v2.extend_from_slice(&crc.to_le_bytes());
    let old = codec::read_file(&v2, ReadLimits::default()).unwrap();
    assert_eq!(old.tree.leaf_records(), None);
    assert_eq!(old.tree.nodes(), tree.nodes());
    // And as version 3: the slices' length goes.
    let mut v3 = pre5[..pre5.len() - 4].to_vec();
    v3[8..10].copy_from_slice(&3u16.to_le_bytes());
    let crc = codec::crc32(&v3);
    v3.extend_from_slice(&crc.to_le_bytes());
    let old3 = codec::read_file(&v3, ReadLimits::default()).unwrap();
    assert_eq!(
        old3.tree,
        codec::read_file(&good, ReadLimits::default()).unwrap().tree
    );
    assert!(old3.slices.is_none());
    assert!(Pvs::from_bytes(&v2).is_ok());
    // Records that lie: a count that does not match, a varint that runs
    // off the end, bytes left over.
    let with_records = |records: &[u8]| {
        let mut b = good[..good.len() - 8 - records_len].to_vec();
        b.extend_from_slice(&(records.len() as u32).to_le_bytes());
        b.extend_from_slice(records);
        b.extend_from_slice(&[0; 4]);
        let crc = codec::crc32(&b);
        b.extend_from_slice(&crc.to_le_bytes());
        codec::read_file(&b, ReadLimits::default())
    };
    let e = with_records(&[1, 2, 3]).unwrap_err();
    assert!(e.to_string().contains("leaf records"), "{e}");
    let mut long = vec![0u8; 3 * tree.leaf_count()];
    *long.last_mut().unwrap() = 0x80;
    let e = with_records(&long).unwrap_err();
    assert!(e.to_string().contains("leaf records end"), "{e}");
    let mut over = vec![0u8; 3 * tree.leaf_count() + 1];
    over[0] = 0;
    let e = with_records(&over).unwrap_err();
    assert!(e.to_string().contains("left over"), "{e}");
    let mut huge = vec![0u8; 3 * tree.leaf_count() + 4];
    huge[..5].copy_from_slice(&[0xff, 0xff, 0xff, 0xff, 0x7f]);
    let e = with_records(&huge).unwrap_err();
    assert!(e.to_string().contains("over 32 bits"), "{e}");
    // No records at all is a valid file.
    let none = with_records(&[]).unwrap();
    assert_eq!(none.tree.leaf_records(), None);
    assert_eq!(none.objects.len(), s.objects().len());
}

/// Prefetch (issue 15, papers/001 sec. 6.1): deltas are the set
/// differences of the answers, leaf deltas those of the leaf sets, and a
/// box of positions answers a superset of every view from inside it.
#[test]
fn deltas_and_prefetch_answer_as_the_set_differences() {
    let bytes = file_bytes(None);
    let pvs = Pvs::from_bytes(&bytes).unwrap();
    let space = pvs.view_box();
    let mut rng = Pcg64::seed_from_u64(16);
    let (mut from, mut to, mut delta) = (pvs.new_set(), pvs.new_set(), pvs.new_delta());
    let (mut entered, mut left) = (0, 0);
    for _ in 0..200 {
        let a = View::look(
            uniform_point(&mut rng, &space),
            uniform_direction(&mut rng),
            Vec3::Z,
            1.0,
            1.6,
        );
        let mut b = a;
        b.position = a.position + uniform_direction(&mut rng) * 0.3;
        b.dir = a.dir + uniform_direction(&mut rng) * 0.2;
        pvs.query_view(&a, &mut from).unwrap();
        pvs.query_view(&b, &mut to).unwrap();
        pvs.delta(&from, &to, &mut delta).unwrap();
        let (mut enter, mut leave) = (to.clone(), from.clone());
        enter.subtract(&from);
        leave.subtract(&to);
        assert_eq!((&delta.entering, &delta.leaving), (&enter, &leave));
        entered += enter.count();
        left += leave.count();
    }
    assert!(entered > 0 && left > 0, "{entered} {left}");
    // Leaves: the difference of their sets; outside, every object.
    for _ in 0..200 {
        let p = |rng: &mut Pcg64| {
            let q = uniform_point(rng, &space);
            let (t, ph) = direction_to_angles(uniform_direction(rng));
            [q.x, q.y, q.z, t, ph]
        };
        let (a, b) = (p(&mut rng), p(&mut rng));
        assert_eq!(pvs.leaf_delta(a, b, &mut delta), Ok(Answer::Tree));
        let n = pvs.object_count();
        let set = |p| {
            let mut s = ObjectSet::new(n);
            pvs.leaf_set(p, &mut s).unwrap();
            s
        };
        let (mut enter, mut leave) = (set(b), set(a));
        enter.subtract(&set(a));
        leave.subtract(&set(b));
        assert_eq!((&delta.entering, &delta.leaving), (&enter, &leave));
    }
    let outside = [space.max.x + 1.0, 0.0, 0.0, 0.0, 1.0];
    let centre = space.center();
    let inside = [centre.x, centre.y, centre.z, 0.0, 1.0];
    assert_eq!(
        pvs.leaf_delta(inside, outside, &mut delta),
        Ok(Answer::Everything)
    );
    assert!(delta.leaving.is_empty());
    // A box of positions: every view from inside it answers a subset.
    let mut ahead = pvs.new_set();
    for _ in 0..30 {
        let c = uniform_point(&mut rng, &space);
        let half = Vec3::new(rng.random(), rng.random(), rng.random()) * 0.5;
        let b = Aabb::new(c - half, c + half);
        let clipped = Aabb::new(b.min.max(space.min), b.max.min(space.max));
        assert_eq!(pvs.query_positions(&clipped, &mut ahead), Ok(Answer::Tree));
        for _ in 0..30 {
            let view = View::square(
                uniform_point(&mut rng, &clipped),
                uniform_direction(&mut rng),
                120.0,
            );
            pvs.query_view(&view, &mut to).unwrap();
            assert!(to.is_subset(&ahead));
        }
        assert_eq!(
            pvs.query_positions(
                &b.union(&Aabb::new(space.max + 1.0, space.max + 1.0)),
                &mut ahead
            ),
            Ok(Answer::Everything)
        );
    }
    // Sets of another size are refused.
    let mut small = ObjectSet::new(3);
    assert!(pvs.delta(&from, &small, &mut delta).is_err());
    assert!(pvs.query_positions(&space, &mut small).is_err());
    let mut bad = Delta {
        entering: ObjectSet::new(3),
        leaving: ObjectSet::new(3),
    };
    assert!(pvs.leaf_delta(inside, inside, &mut bad).is_err());
    // What the loaded file takes in memory.
    let memory = pvs.memory_bytes();
    eprintln!(
        "{} bytes on disk, {memory} in memory ({:.1}x)",
        bytes.len(),
        memory as f64 / bytes.len() as f64
    );
    assert!(memory > pvs.node_count() * 8);
}

/// Ids in the file (version 5): two objects with one id are refused; the
/// builder writes the default ids.
#[test]
fn ids_are_unique_in_a_file_and_default_before_version_5() {
    let (s, _, tree) = apartment();
    let mut file = to_file(s, tree.clone(), &BuildParams::default(), None);
    file.objects[1].id = file.objects[0].id.clone();
    let err = codec::read_file(&codec::write_file(&file), ReadLimits::default()).unwrap_err();
    assert!(
        matches!(&err, CodecError::Corrupt(m) if m.contains("two objects have the id")),
        "{err}"
    );
    // The builder's ids are the default ones (files before version 5 get
    // them too: `leaf_records_round_trip_and_lies_are_refused`).
    let good = file_bytes(None);
    let v5 = codec::read_file(&good, ReadLimits::default()).unwrap();
    let names: Vec<&str> = v5.objects.iter().map(|o| o.name.as_str()).collect();
    assert_eq!(
        v5.objects.iter().map(|o| o.id.clone()).collect::<Vec<_>>(),
        codec::default_ids(names)
    );
}

/// A version 6 file's body (no checksum) as version 5 lays it out: the
/// objects' flags bytes (each 0) cut.
fn before_version_6(v6: &[u8], objects: usize) -> Vec<u8> {
    let u16_at = |b: &[u8], k: usize| u16::from_le_bytes([b[k], b[k + 1]]) as usize;
    let mut out = v6.to_vec();
    // The parameters' length at 121 (after the up byte and the bounds
    // grid), then the table: u32 triangles, 6 x u16 bounds, u16 name
    // length, the name, u16 id length, the id, u8 flags.
    let params = u32::from_le_bytes(out[121..125].try_into().unwrap()) as usize;
    let mut k = 125 + params;
    for _ in 0..objects {
        k += 4 + 12;
        k += 2 + u16_at(&out, k);
        k += 2 + u16_at(&out, k);
        assert_eq!(out.remove(k), 0, "flags");
    }
    out
}

/// A version 6 file's body (no checksum) as version 4 lays it out: the up
/// byte (+z), the objects' id lengths (each 0: ids equal to names) and
/// their flags (each 0) cut.
fn before_version_5(v6: &[u8], objects: usize) -> Vec<u8> {
    let u16_at = |b: &[u8], k: usize| u16::from_le_bytes([b[k], b[k + 1]]) as usize;
    let mut out = before_version_6(v6, objects);
    assert_eq!(out.remove(96), 2, "the up axis");
    // The parameters' length at 120 (after the bounds grid), then the
    // table: u32 triangles, 6 x u16 bounds, u16 name length, the name,
    // u16 id length.
    let params = u32::from_le_bytes(out[120..124].try_into().unwrap()) as usize;
    let mut k = 124 + params;
    for _ in 0..objects {
        k += 4 + 12;
        k += 2 + u16_at(&out, k);
        assert_eq!(u16_at(&out, k), 0, "an id other than the name");
        out.drain(k..k + 2);
    }
    out
}

/// Flags in the file (version 6): they round-trip, unknown bits are
/// refused, and a version 5 file reads as no flags.
#[test]
fn flags_round_trip_and_version_5_has_none() {
    use vis5d::codec::ObjectFlags;
    let (s, _, tree) = apartment();
    let mut file = to_file(s, tree.clone(), &BuildParams::default(), None);
    file.objects[2].flags = ObjectFlags::ALWAYS_VISIBLE.union(ObjectFlags::NEVER_OCCLUDER);
    let back = codec::read_file(&codec::write_file(&file), ReadLimits::default()).unwrap();
    let flags = |f: &codec::V5dFile| f.objects.iter().map(|o| o.flags).collect::<Vec<_>>();
    assert_eq!(flags(&back), flags(&file));
    // As version 5 (no flags bytes) the same file.
    let good = file_bytes(None);
    let plain = codec::read_file(&good, ReadLimits::default()).unwrap();
    let body = &good[..good.len() - 4];
    let v5 = before_version_6(body, plain.objects.len());
    assert_eq!(body.len() - v5.len(), plain.objects.len());
    let mut v5 = v5;
    v5[8..10].copy_from_slice(&5u16.to_le_bytes());
    let crc = codec::crc32(&v5);
    v5.extend_from_slice(&crc.to_le_bytes());
    assert_eq!(codec::read_file(&v5, ReadLimits::default()).unwrap(), plain);
    // Object 0's flags byte: after its name and its id (both the name).
    let params = u32::from_le_bytes(body[121..125].try_into().unwrap()) as usize;
    let name = plain.objects[0].name.len();
    let at = 125 + params + 4 + 12 + 2 + name + 2;
    let mut bad = body.to_vec();
    assert_eq!(bad[at], 0);
    bad[at] = 0x84;
    let crc = codec::crc32(&bad);
    bad.extend_from_slice(&crc.to_le_bytes());
    let err = codec::read_file(&bad, ReadLimits::default()).unwrap_err();
    assert!(err.to_string().contains("unknown flags 0x84"), "{err}");
}
