//! The conservative bake (`vis5d build --conservative`): a spatial tree of
//! the oracle's sets that no ray and no rendered pixel catches missing an
//! object, answered by the same `Pvs` as the sampled tree.

use glam::Vec3;
use rand::SeedableRng;
use rand_pcg::Pcg64;
use vis5d::builder::{BuildParams, file_with_params, to_file};
use vis5d::codec::write_file;
use vis5d::conservative::{BakeError, BakeParams, bake};
use vis5d::oracle::{Oracle, OracleParams, Rasteriser};
use vis5d::query::Pvs;
use vis5d::random::{uniform_direction, uniform_point};
use vis5d::render::{Camera, IdBuffer, random_views};
use vis5d::scene::{self, Scene};
use vis5d::trace::{Ray, Tracer};
use vis5d::tree::VisTree;

use crate::{committed, vis5d};

fn small() -> BakeParams {
    BakeParams {
        max_depth: 5,
        triangle_budget: Some(0),
        ..BakeParams::default()
    }
}

fn bake_with(s: &Scene, rasteriser: Rasteriser, params: &BakeParams) -> VisTree {
    let oracle = Oracle::new(s, OracleParams::default(), rasteriser).unwrap();
    let (tree, stats) = bake(&oracle, params, &|_| {}).unwrap();
    assert!(stats.cells as usize >= tree.nodes().len());
    tree.validate().unwrap();
    tree
}

/// Every object that a pixel of a random view, or a random ray from a
/// random point of a leaf's box, hits first is in the answer: through
/// `Pvs::query_view` (culled to the frustum) for the views, in the leaf's
/// set for the rays. Returns the mean answer over the mean objects seen.
fn assert_never_misses(name: &str, s: &Scene, tree: VisTree, views: usize) -> f64 {
    let tracer = Tracer::new(s);
    let oracle = Oracle::new(s, OracleParams::default(), Rasteriser::cpu()).unwrap();
    let params = small().to_text(&oracle);
    let bytes = write_file(&file_with_params(s, tree.clone(), params, None));
    let pvs = Pvs::from_bytes(&bytes).unwrap();
    assert!(pvs.is_conservative(), "{name}");
    let mut answer = pvs.new_set();
    let (mut drawn, mut seen, mut hit_pixels) = (0usize, 0usize, 0u64);
    for (i, view) in random_views(&pvs.root_cell().space(), views, 90.0, 5)
        .iter()
        .enumerate()
    {
        pvs.query_view(view, &mut answer).unwrap();
        let ids = IdBuffer::render(&tracer, &Camera::new(view, 64, 64).unwrap());
        hit_pixels += ids.hit_pixels();
        for (o, n) in ids.object_pixels(s.objects().len()) {
            if n > 0 {
                seen += 1;
                assert!(
                    answer.contains(o as usize),
                    "{name}: view {i} sees {} on {n} pixels; the conservative answer lacks it",
                    s.objects()[o as usize].name
                );
            }
        }
        drawn += answer.count();
    }
    assert!(
        hit_pixels > (views * 64 * 64 / 4) as u64,
        "{name}: few pixels hit"
    );
    let mut rng = Pcg64::seed_from_u64(9);
    for leaf in tree.leaves() {
        let space = leaf.cell.space();
        let set = &tree.nodes()[leaf.node].set;
        for _ in 0..200 {
            let p: Vec3 = uniform_point(&mut rng, &space);
            if let Some(h) = tracer.closest_hit(&Ray::new(p, uniform_direction(&mut rng))) {
                assert!(
                    set.contains(h.object as usize),
                    "{name}: a ray from {p} in leaf {} hits {}, which its set lacks",
                    leaf.node,
                    s.objects()[h.object as usize].name
                );
            }
        }
    }
    drawn as f64 / seen.max(1) as f64
}

/// On every committed scene, CPU rasteriser: no pixel of 40 random views
/// and no ray of 200 per leaf finds an object the tree lacks, and the
/// tree proves something hidden (its leaves are not all full).
#[test]
fn the_conservative_tree_misses_nothing_on_every_committed_scene() {
    for name in ["apartment", "office", "city", "forest", "machine"] {
        let s = scene::load(committed(&format!("{name}.obj"))).unwrap();
        let tree = bake_with(&s, Rasteriser::cpu(), &small());
        // Cut to the depth limit, or less where a set fell under the
        // budget of 0 triangles (an empty set).
        assert!(tree.leaf_count() <= 32, "{name}");
        let n = s.objects().len();
        let mean: f64 = tree
            .leaves()
            .iter()
            .map(|l| tree.nodes()[l.node].set.count() as f64)
            .sum::<f64>()
            / tree.leaf_count() as f64;
        if name != "forest" && name != "city" {
            // The committed forest is too sparse for the oracle to hide
            // anything, and from the city's cells at this depth (tens of
            // metres, over the roofs) it proves nothing either
            // (notes/oracle.md).
            assert!(mean < n as f64, "{name}: nothing proved hidden");
        }
        let ratio = assert_never_misses(name, &s, tree, 40);
        eprintln!(
            "{name}: leaves hold {mean:.1} of {n} objects; a view draws {ratio:.2}x what it sees"
        );
    }
}

/// With the GPU rasteriser (CI: Mesa's lavapipe) the tree is never wrong
/// either.
#[test]
fn the_conservative_tree_on_the_gpu_misses_nothing() {
    let Some(gpu) = crate::oracle::gpu() else {
        return;
    };
    let s = scene::load(committed("office.obj")).unwrap();
    let params = BakeParams {
        max_depth: 3,
        ..small()
    };
    let tree = bake_with(&s, Rasteriser::gpu(gpu), &params);
    assert_never_misses("office on the GPU", &s, tree, 20);
}

/// The same tree whatever the thread count; a huge budget or depth 0 keeps
/// the root whole; bad settings are refused by name.
#[test]
fn the_bake_is_deterministic_and_checks_its_settings() {
    let s = scene::load(committed("office.obj")).unwrap();
    let params = BakeParams {
        max_depth: 4,
        ..small()
    };
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap()
        .install(|| bake_with(&s, Rasteriser::cpu(), &params));
    let three = rayon::ThreadPoolBuilder::new()
        .num_threads(3)
        .build()
        .unwrap()
        .install(|| bake_with(&s, Rasteriser::cpu(), &params));
    assert_eq!(one, three);
    // Trying every side's cut: the same for any thread count, and as sound.
    let tried = BakeParams {
        try_cuts: true,
        ..params.clone()
    };
    let pool = |n| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build()
            .unwrap()
    };
    let tried_one = pool(1).install(|| bake_with(&s, Rasteriser::cpu(), &tried));
    let tried_two = pool(2).install(|| bake_with(&s, Rasteriser::cpu(), &tried));
    assert_eq!(tried_one, tried_two);
    assert_ne!(tried_one, one, "another cut somewhere");
    assert_never_misses("office, cuts tried", &s, tried_one, 20);
    // Stopping where levels prove nothing: the city's big cells prove
    // nothing, so its tree stops after three levels, and stays sound.
    let city = scene::load(committed("city.obj")).unwrap();
    let stalling = BakeParams {
        stall_levels: 3,
        ..small()
    };
    let stalled = bake_with(&city, Rasteriser::cpu(), &stalling);
    assert!(stalled.leaf_count() < 32, "{}", stalled.leaf_count());
    assert_never_misses("city, stalling", &city, stalled, 20);
    for whole in [
        BakeParams {
            triangle_budget: Some(u64::MAX),
            ..small()
        },
        BakeParams {
            max_depth: 0,
            ..small()
        },
    ] {
        assert_eq!(bake_with(&s, Rasteriser::cpu(), &whole).leaf_count(), 1);
    }
    let oracle = Oracle::new(&s, OracleParams::default(), Rasteriser::cpu()).unwrap();
    // Progress reaches the whole view box, deep leaves included.
    let reached = std::sync::Mutex::new(0.0f64);
    bake(
        &oracle,
        &BakeParams {
            max_depth: 6,
            stall_levels: 0,
            ..small()
        },
        &|f| {
            let mut r = reached.lock().unwrap();
            *r = r.max(f);
        },
    )
    .unwrap();
    assert!((*reached.lock().unwrap() - 1.0).abs() < 1e-9);
    for (bad, name) in [
        (
            BakeParams {
                view_box: Some(vis5d::geom::Aabb::new(
                    Vec3::new(-1e19, -1.0, -1.0),
                    Vec3::new(1e19, 1.0, 1.0),
                )),
                ..small()
            },
            "view_box",
        ),
        (
            BakeParams {
                min_cell_fraction: 0.7,
                ..small()
            },
            "min_cell_fraction",
        ),
        (
            BakeParams {
                grid_bits: 0,
                ..small()
            },
            "grid_bits",
        ),
        (
            BakeParams {
                view_grow: f32::NAN,
                ..small()
            },
            "view_grow",
        ),
    ] {
        match bake(&oracle, &bad, &|_| {}) {
            Err(BakeError::Parameter { name: n, .. }) => assert_eq!(n, name),
            other => panic!("{name}: {other:?}"),
        }
    }
    assert_eq!(
        bake(
            &oracle,
            &BakeParams {
                max_nodes: 62,
                ..small()
            },
            &|_| {}
        )
        .map(|_| ()),
        Err(BakeError::TooManyNodes { max_nodes: 62 })
    );
    // A sampled tree's file does not say conservative.
    let tracer = Tracer::new(&s);
    let sampled = BuildParams {
        max_depth: 2,
        ..BuildParams::default()
    };
    let (tree, _) = vis5d::builder::build(&s, &tracer, &sampled, &|_| {}).unwrap();
    let pvs = Pvs::from_bytes(&write_file(&to_file(&s, tree, &sampled, None))).unwrap();
    assert!(!pvs.is_conservative());
}

/// The command: `build --conservative` writes a file that `stat` calls
/// conservative and `query` answers; the sampler's flags are refused with
/// it, and its own flags without it.
#[test]
fn build_conservative_from_the_command_line() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("office.v5d");
    let model = committed("office.obj");
    let o = vis5d(&[
        "build",
        model.to_str().unwrap(),
        "--conservative",
        "--max-depth",
        "3",
        "--try-cuts",
        "--verify-views",
        "10",
        "--json",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(j["method"], "conservative");
    assert_eq!(j["rasteriser"], "CPU", "the bake's default");
    assert_eq!(j["leaves"], 8);
    assert_eq!(j["nodes"], 15);
    // Trying the cuts runs the oracle on halves not taken.
    assert!(j["oracle_cells"].as_u64().unwrap() > 15);
    assert_eq!(j["pixel_error"]["missing_pixels"], 0);
    let o = vis5d(&["stat", out.to_str().unwrap(), "--json"]);
    assert!(o.status.success());
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(j["method"], "conservative");
    // --gpu: wgpu where an adapter exists (CI requires one: lavapipe).
    let o = vis5d(&[
        "build",
        model.to_str().unwrap(),
        "--conservative",
        "--gpu",
        "--max-depth",
        "2",
        "--dry-run",
        "--json",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    if std::env::var_os("VIS5D_REQUIRE_GPU").is_some() {
        assert!(
            j["rasteriser"].as_str().unwrap().starts_with("GPU: "),
            "{j}"
        );
    }
    for (flags, says) in [
        (vec!["--conservative", "--s-thresh", "0.02"], "--s-thresh"),
        (vec!["--conservative", "--edge-rays", "2"], "--edge-rays"),
        (vec!["--triangle-budget", "100"], "--conservative"),
        (vec!["--gpu"], "--conservative"),
        (vec!["--conservative", "--min-cell", "0.7"], "--min-cell"),
        (
            vec!["--conservative", "--view-box=-1e19,-1,-1,1e19,1,1"],
            "--view-box",
        ),
        // The sampled build too (its root box was NaN).
        (vec!["--view-box=-1e19,-1,-1,1e19,1,1"], "--view-box"),
        (
            vec!["--conservative", "--max-depth", "64", "--min-cell", "1e-6"],
            "--max-nodes",
        ),
    ] {
        let mut args = vec!["build", model.to_str().unwrap(), "--dry-run"];
        args.extend(flags.iter().copied());
        let o = vis5d(&args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{flags:?}");
        assert!(err.contains(says), "{flags:?}: {err}");
    }
}

/// `vis5d report --conservative FILE` adds a "conservative tree" row that
/// loses no pixel, beside the sampled tree's; a sampled file there is
/// refused.
#[test]
fn the_report_shows_the_conservative_tree_beside_the_sampled_one() {
    let dir = tempfile::tempdir().unwrap();
    let model = committed("office.obj");
    let model = model.to_str().unwrap();
    let (cons, samp) = (dir.path().join("c.v5d"), dir.path().join("s.v5d"));
    let (cons, samp) = (cons.to_str().unwrap(), samp.to_str().unwrap());
    for args in [
        vec![
            "build",
            model,
            "--conservative",
            "--max-depth",
            "4",
            "-o",
            cons,
        ],
        vec!["build", model, "--max-depth", "6", "-o", samp],
    ] {
        let o = vis5d(&args);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    let rep = dir.path().join("rep");
    let o = vis5d(&[
        "report",
        model,
        "--pvs",
        samp,
        "--conservative",
        cons,
        "--random",
        "30",
        "--resolution",
        "64",
        "--no-oracle",
        "-o",
        rep.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(rep.join("report.json")).unwrap()).unwrap();
    let row = |name: &str| {
        j["methods"]
            .as_array()
            .unwrap()
            .iter()
            .find(|m| m["name"] == name)
            .unwrap_or_else(|| panic!("no {name} row"))["summary"]
            .clone()
    };
    let (c, f) = (row("conservative tree"), row("frustum"));
    assert_eq!(c["mean_pixel_error"], 0.0);
    assert!(c["mean_objects"].as_f64().unwrap() < f["mean_objects"].as_f64().unwrap());
    row("vis5d");
    let html = std::fs::read_to_string(rep.join("index.html")).unwrap();
    assert!(html.contains("conservative tree"));
    let o = vis5d(&[
        "report",
        model,
        "--pvs",
        samp,
        "--conservative",
        samp,
        "--random",
        "3",
        "--no-oracle",
        "-o",
        dir.path().join("bad").to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("not a conservative tree"));
}
