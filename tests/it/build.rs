//! The builder: tree invariants, visibility checked against rendered rays,
//! scenes whose answer is known by construction, determinism.

use std::path::Path;

use glam::Vec3;
use vis5d::builder::{
    BuildParams, BuildStats, SplitScore, VerifyParams, build, pixel_error, summarize,
};
use vis5d::geom::Aabb;
use vis5d::geom::cell::{DIMS, THETA};
use vis5d::scene::procedural::shapes::push_box;
use vis5d::scene::{self, Scene, SceneBuilder, SceneFormat};
use vis5d::trace::Tracer;
use vis5d::tree::VisTree;

fn build_default(s: &Scene, params: &BuildParams) -> (Tracer, VisTree) {
    let tracer = Tracer::new(s);
    let (tree, _) = build(s, &tracer, params, &|_| {}).unwrap();
    tree.validate().unwrap();
    (tracer, tree)
}

/// Asserts a pixel error under 0.1% over `views` random views of 48x48
/// pixels rendered by ray casting.
fn assert_sees_what_renders_see(
    name: &str,
    s: &Scene,
    tracer: &Tracer,
    tree: &VisTree,
    views: u32,
) {
    let v = VerifyParams {
        views,
        resolution: 48,
        ..VerifyParams::default()
    };
    let e = pixel_error(s, tracer, tree, &v);
    assert!(
        e.fraction() < 0.001,
        "{name}: pixel error {} ({:?})",
        e.fraction(),
        e.missing_objects
    );
}

/// Pixel error below 0.1% with default parameters on every committed
/// scene (notes/build.md has the figures with more views), and the tree's
/// invariants hold.
#[test]
fn default_build_sees_what_renders_see() {
    for name in ["apartment", "office", "city", "forest", "machine"] {
        let s = scene::load(crate::committed(&format!("{name}.obj"))).unwrap();
        let (tracer, tree) = build_default(&s, &BuildParams::default());
        let v = VerifyParams {
            views: 40,
            resolution: 48,
            ..VerifyParams::default()
        };
        let e = pixel_error(&s, &tracer, &tree, &v);
        assert!(
            e.hit_pixels > 40 * 48 * 48 / 4,
            "{name}: only {} pixels hit",
            e.hit_pixels
        );
        assert!(
            e.fraction() < 0.001,
            "{name}: pixel error {} ({:?})",
            e.fraction(),
            e.missing_objects
        );
        let sum = summarize(&tree, &s);
        assert!(sum.leaves > 10, "{name}: {} leaves", sum.leaves);
        // Tight: a random view ray's set holds well under half the scene.
        assert!(
            sum.measure_weighted_objects < 0.5 * s.objects().len() as f64,
            "{name}: {sum:?}"
        );
    }
}

/// Every named preset of the build parameters is valid and builds a tree
/// that sees what renders see, on the apartment of papers/003.
#[test]
fn every_preset_builds_a_tree_that_sees_what_renders_see() {
    let s = scene::load(crate::committed("apartment.obj")).unwrap();
    for (name, params) in BuildParams::presets() {
        params.validate().unwrap();
        let (tracer, tree) = build_default(&s, &params);
        assert_sees_what_renders_see(name, &s, &tracer, &tree, 20);
        assert!(tree.depth() <= params.max_depth, "{name}");
    }
}

/// Two sealed boxy rooms, each with three cubes inside: from inside the
/// first, every wall and cube of the first is visible (a convex room sees
/// all of itself) and nothing of the second.
#[test]
fn a_sealed_room_sees_itself_and_nothing_else() {
    let mut b = SceneBuilder::new(SceneFormat::Procedural);
    for (r, x0) in [(0, 0.0f32), (1, 10.0)] {
        let o = Vec3::new(x0, 0.0, 0.0);
        let (t, w) = (0.1, 4.0);
        let walls = [
            (Vec3::new(0.0, 0.0, -t), Vec3::new(w, w, 0.0)),
            (Vec3::new(0.0, 0.0, w), Vec3::new(w, w, w + t)),
            (Vec3::new(-t, 0.0, 0.0), Vec3::new(0.0, w, w)),
            (Vec3::new(w, 0.0, 0.0), Vec3::new(w + t, w, w)),
            (Vec3::new(0.0, -t, 0.0), Vec3::new(w, 0.0, w)),
            (Vec3::new(0.0, w, 0.0), Vec3::new(w, w + t, w)),
        ];
        for (k, (lo, hi)) in walls.into_iter().enumerate() {
            let mut tris = Vec::new();
            push_box(&mut tris, o + lo, o + hi);
            b.begin_object(format!("room{r}/wall{k}"));
            for t in tris {
                b.push_triangle(t).unwrap();
            }
        }
        for k in 0..3 {
            let c = o + Vec3::new(1.0 + k as f32, 1.0 + 0.5 * k as f32, 0.0);
            let mut tris = Vec::new();
            push_box(&mut tris, c, c + Vec3::splat(0.5));
            b.begin_object(format!("room{r}/cube{k}"));
            for t in tris {
                b.push_triangle(t).unwrap();
            }
        }
    }
    let s = b.finish(Path::new("rooms")).unwrap();
    let params = BuildParams {
        view_box: Some(Aabb::new(Vec3::splat(0.2), Vec3::new(3.8, 3.8, 3.8))),
        min_visible_triangles: 0,
        ..BuildParams::default()
    };
    let (_, tree) = build_default(&s, &params);
    let root = &tree.nodes()[0].set;
    let names: Vec<&str> = root.iter().map(|o| s.objects()[o].name.as_str()).collect();
    assert_eq!(root.count(), 9, "{names:?}");
    assert!(names.iter().all(|n| n.starts_with("room0/")), "{names:?}");
    for l in tree.leaves() {
        assert!(tree.nodes()[l.node].set.iter().all(|o| o < 9));
    }
}

#[test]
fn same_seed_same_tree_whatever_the_thread_count() {
    let s = scene::load(crate::committed("machine.obj")).unwrap();
    let tracer = Tracer::new(&s);
    let params = BuildParams::default();
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| build(&s, &tracer, &params, &|_| {}).unwrap())
    };
    let (one, stats_one) = run(1);
    let (two, stats_two) = run(2);
    let (three, _) = run(3);
    assert!(
        one == two && two == three,
        "trees differ across thread counts"
    );
    assert_eq!(stats_one.rays(), stats_two.rays());
    assert_eq!(stats_one.decisions, stats_two.decisions);
    let other = BuildParams { seed: 2, ..params };
    let (reseeded, _) = build(&s, &tracer, &other, &|_| {}).unwrap();
    assert!(reseeded != one, "the seed changes nothing");
}

/// With a fixed top (`top_levels`), the subtrees are built in parallel
/// and put together in their order: the same tree whatever the thread
/// count, and the fixed nodes' sets are the unions of their children's.
#[test]
fn a_fixed_top_builds_the_same_tree_whatever_the_thread_count() {
    let s = scene::load(crate::committed("machine.obj")).unwrap();
    let tracer = Tracer::new(&s);
    let params = BuildParams {
        top_levels: 2,
        max_depth: 7,
        ..BuildParams::default()
    };
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| build(&s, &tracer, &params, &|_| {}).unwrap().0)
    };
    let (one, two) = (run(1), run(2));
    assert!(one == two, "trees differ across thread counts");
    one.validate().unwrap();
    // The top two levels are the fixed cuts: spatial, at the midpoints.
    let n = one.nodes();
    for i in [0, 1, n[0].split.unwrap().above as usize] {
        let sp = n[i].split.expect("a fixed node is split");
        assert!((sp.dim as usize) < THETA, "node {i} is cut in {}", sp.dim);
        assert_eq!(sp.code, 1 << (params.grid_bits - 1), "node {i}");
    }
    // And the default (no fixed top) is a different tree.
    let (plain, _) = build(
        &s,
        &tracer,
        &BuildParams {
            top_levels: 0,
            ..params.clone()
        },
        &|_| {},
    )
    .unwrap();
    assert!(plain != one);
}

/// The builder's sampling and tracing run in code compiled for AVX2 and
/// FMA where the CPU has them (`Tracer::is_wide`), else in portable code:
/// the same operations in the same order, so the same tree and the same
/// rays, whichever ran.
#[test]
fn the_wide_and_the_portable_code_build_the_same_tree() {
    for name in ["machine.obj", "apartment.obj"] {
        let s = scene::load(crate::committed(name)).unwrap();
        let params = BuildParams {
            max_depth: 8,
            ..BuildParams::default()
        };
        let wide = Tracer::new(&s);
        let portable = Tracer::new(&s).with_portable_code();
        assert!(!portable.is_wide());
        let (a, sa) = build(&s, &wide, &params, &|_| {}).unwrap();
        let (b, sb) = build(&s, &portable, &params, &|_| {}).unwrap();
        assert!(a == b, "{name}: the trees differ");
        assert_eq!(sa.rays(), sb.rays(), "{name}");
        assert_eq!(sa.rejected, sb.rejected, "{name}");
    }
}

#[test]
fn spatial_only_with_angular_leaves() {
    let s = scene::load(crate::committed("apartment.obj")).unwrap();
    let params = BuildParams {
        spatial_only: true,
        angular_leaves: 8,
        ..BuildParams::default()
    };
    let (_, tree) = build_default(&s, &params);
    // Every leaf sits under exactly three angular cuts, and no spatial cut
    // is below an angular one.
    fn walk(tree: &VisTree, i: usize, angular_above: u32) {
        match tree.nodes()[i].split {
            None => assert_eq!(angular_above, 3, "leaf {i}"),
            Some(sp) => {
                let angular = sp.dim as usize >= THETA;
                assert!(
                    angular || angular_above == 0,
                    "spatial split {i} under an angular one"
                );
                let a = angular_above + angular as u32;
                walk(tree, i + 1, a);
                walk(tree, sp.above as usize, a);
            }
        }
    }
    walk(&tree, 0, 0);
    assert_eq!(tree.leaf_count() % 8, 0);
}

#[test]
fn leaves_hold_their_rays() {
    // Every ray of a leaf's cell locates to that leaf.
    let s = scene::load(crate::committed("office.obj")).unwrap();
    let (_, tree) = build_default(&s, &BuildParams::default());
    for l in tree.leaves() {
        let c = l.cell;
        let centre: [f32; DIMS] = std::array::from_fn(|d| 0.5 * (c.lo[d] + c.hi[d]));
        assert_eq!(tree.locate(centre), l.node);
        assert_eq!(
            tree.locate(c.lo),
            l.node,
            "the low corner is inside (half-open cells)"
        );
    }
}

#[test]
fn view_box_and_growth() {
    let s = scene::load(crate::committed("apartment.obj")).unwrap();
    let b = Aabb::new(Vec3::new(1.0, 1.0, 0.5), Vec3::new(3.0, 2.0, 1.5));
    let params = BuildParams {
        view_box: Some(b),
        view_grow: 0.1,
        max_depth: 4,
        ..BuildParams::default()
    };
    let (_, tree) = build_default(&s, &params);
    let root = tree.root_cell().space();
    let g = 0.1 * b.diagonal();
    assert!((root.min - (b.min - Vec3::splat(g))).length() < 1e-5);
    assert!((root.max - (b.max + Vec3::splat(g))).length() < 1e-5);
    assert_eq!(params.root_box(&s), root);
}

#[test]
fn bad_parameters_are_refused() {
    let s = scene::load(crate::committed("apartment.obj")).unwrap();
    let tracer = Tracer::new(&s);
    let ok = BuildParams::default();
    for (bad, want) in [
        (
            BuildParams {
                angular_leaves: 3,
                ..ok.clone()
            },
            "power of two",
        ),
        (
            BuildParams {
                grid_bits: 0,
                ..ok.clone()
            },
            "grid_bits",
        ),
        (
            BuildParams {
                split_threshold: 1.5,
                ..ok.clone()
            },
            "threshold",
        ),
        (
            BuildParams {
                view_box: Some(Aabb::new(Vec3::ONE, Vec3::ZERO)),
                ..ok.clone()
            },
            "view_box",
        ),
    ] {
        let Err(e) = build(&s, &tracer, &bad, &|_| {}) else {
            panic!("{bad:?} was accepted");
        };
        assert!(e.to_string().contains(want), "{e}");
    }
    let mut low = ok.clone();
    low.sprt.s_thresh = 0.0001;
    let Err(e) = build(&s, &tracer, &low, &|_| {}) else {
        panic!("s_thresh 0.0001 was accepted");
    };
    assert!(e.to_string().contains("before any ray hits"), "{e}");
}

#[test]
fn cli_defaults_are_the_library_defaults() {
    // `vis5d build` states its SPRT prior as text; keep it in step.
    let p = BuildParams::default().sprt;
    let help = std::process::Command::new(env!("CARGO_BIN_EXE_vis5d"))
        .args(["build", "--help"])
        .output()
        .unwrap();
    let help = String::from_utf8_lossy(&help.stdout);
    assert!(
        help.contains(&format!("[default: {},{}]", p.prior_a, p.prior_b)),
        "{help}"
    );
}

/// Leaves retest what their ancestors dropped (issue 12: an object seen
/// from a small part of a big cell falls under the SPRT's threshold there
/// and was lost to the whole subtree). The retest only adds objects a ray
/// hit: the tree has the same cells, every set holds the sets built
/// without it, and on the office some leaves gain objects.
#[test]
fn leaves_find_what_their_ancestors_dropped() {
    // The office finds objects; the apartment and the machine are where a
    // review found the first version losing some (a retest ray that proved
    // a candidate early stopped the samples that would have proven a
    // third object).
    for name in ["office", "apartment", "machine"] {
        retest_only_adds(name);
    }
}

fn retest_only_adds(name: &str) {
    let none = BuildParams {
        retest_rays: 0,
        ..BuildParams::default()
    };
    let (d0, d1) = only_adds(name, &none, &BuildParams::default());
    let (d0, d1) = (d0.decisions, d1.decisions);
    assert_eq!((d0.retested, d0.retest_found), (0, 0));
    assert!(d1.retested > 0 && d1.retest_found > 0, "{name}: {d1:?}");
}

/// Builds committed scene `name` with `without` and with `with`, which
/// must differ only by something that adds objects: asserts the same
/// cells, every set of `with` a superset of `without`'s, and some gained.
/// Returns both builds' stats.
fn only_adds(name: &str, without: &BuildParams, with: &BuildParams) -> (BuildStats, BuildStats) {
    let s = scene::load(crate::committed(&format!("{name}.obj"))).unwrap();
    let tracer = Tracer::new(&s);
    let run = |params: &BuildParams| {
        let (tree, stats) = build(&s, &tracer, params, &|_| {}).unwrap();
        tree.validate().unwrap();
        (tree, stats)
    };
    let (a, s0) = run(without);
    let (b, s1) = run(with);
    assert_eq!(a.nodes().len(), b.nodes().len());
    let mut gained = 0;
    for (a, b) in a.nodes().iter().zip(b.nodes()) {
        assert_eq!(a.split, b.split, "the same cells");
        assert!(a.set.is_subset(&b.set), "{name}: only adds");
        gained += b.set.count() - a.set.count();
    }
    assert!(gained > 0, "{name}");
    eprintln!(
        "{name}: {gained} (node, object) pairs gained; {:?}",
        s1.decisions
    );
    (s0, s1)
}

/// Edge rays (GVS's border sampling at the object level) only add objects
/// that a ray of the leaf's cell hit: the same cells, every set a superset
/// of the one built without them, and on the city, whose buildings peek
/// over each other, some found.
#[test]
fn edge_rays_only_add_what_rays_hit() {
    let none = BuildParams {
        edge_rays: 0,
        ..BuildParams::default()
    };
    let (s0, s1) = only_adds("city", &none, &BuildParams::default());
    assert_eq!((s0.edge_rays, s0.decisions.edge_found), (0, 0));
    assert!(s1.edge_rays > 0 && s1.decisions.edge_found > 0, "{s1:?}");
}

/// Object samples traced by a node are handed down to the child they lie
/// in: their hits prove objects there and their misses count in the
/// child's tests. On the city and the office this saves object rays (some
/// tests are decided by the ancestors' samples alone) and the tree still
/// sees what renders see (`default_build_sees_what_renders_see` runs with
/// it on: it is the default).
#[test]
fn inherited_samples_save_object_rays() {
    for name in ["city", "office"] {
        let s = scene::load(crate::committed(&format!("{name}.obj"))).unwrap();
        let tracer = Tracer::new(&s);
        let run = |inherit_samples: bool| {
            let params = BuildParams {
                inherit_samples,
                ..BuildParams::default()
            };
            let (tree, stats) = build(&s, &tracer, &params, &|_| {}).unwrap();
            tree.validate().unwrap();
            stats
        };
        let (without, with) = (run(false), run(true));
        assert_eq!(without.decisions.decided_by_ancestors, 0);
        assert!(with.decisions.decided_by_ancestors > 0, "{name}: {with:?}");
        assert!(
            (with.object_rays as f64) < 0.95 * without.object_rays as f64,
            "{name}: {} object rays with, {} without",
            with.object_rays,
            without.object_rays
        );
    }
}

/// The expected-set split score (`--split-score expected-set`) builds
/// valid trees that see what renders see, on the office (rooms behind
/// walls, where it cuts off thin slabs that E refuses) and the city, and
/// its trees differ from E's.
#[test]
fn the_expected_set_score_sees_what_renders_see() {
    for name in ["office", "city"] {
        let s = scene::load(crate::committed(&format!("{name}.obj"))).unwrap();
        let params = BuildParams {
            split_score: SplitScore::ExpectedSet,
            split_threshold: SplitScore::ExpectedSet.default_threshold(),
            ..BuildParams::default()
        };
        params.validate().unwrap();
        let (tracer, tree) = build_default(&s, &params);
        assert_sees_what_renders_see(name, &s, &tracer, &tree, 40);
        let (_, default) = build_default(&s, &BuildParams::default());
        assert_ne!(tree.leaf_count(), default.leaf_count(), "{name}");
    }
}
