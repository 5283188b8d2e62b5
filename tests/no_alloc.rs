//! The render loop allocates nothing (issue 15): once the answer sets and
//! the delta are made, view queries (local and world), range and box
//! queries, leaf sets and deltas make no heap allocation. A counting
//! global allocator watches; this test binary holds nothing else, so no
//! other test allocates while it counts.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

use glam::{DVec3, Vec3};
use vis5d::query::{Pvs, View};

struct Counting;

static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

// SAFETY: every call is forwarded to the system allocator unchanged.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        // SAFETY: the caller's contract is the system allocator's.
        unsafe { System.alloc(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: as above.
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        // SAFETY: as above.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn the_render_loop_allocates_nothing() {
    use vis5d::scene::procedural::{SceneKind, generate};
    let scene = generate(SceneKind::Apartment, 1, 1);
    let tracer = vis5d::trace::Tracer::new(&scene);
    let params = vis5d::builder::BuildParams {
        max_depth: 8,
        ..Default::default()
    };
    let (tree, _) = vis5d::builder::build(&scene, &tracer, &params, &|_| {}).unwrap();
    let bytes = vis5d::codec::write_file(&vis5d::builder::to_file(&scene, tree, &params, None));
    let pvs = Pvs::from_bytes(&bytes).unwrap();
    let (mut now, mut before, mut delta) = (pvs.new_set(), pvs.new_set(), pvs.new_delta());
    let space = pvs.view_box();
    let views: Vec<View> = (0..500)
        .map(|k| {
            let t = k as f32 / 500.0;
            let eye = space.lerp(Vec3::new(t, 0.5 + 0.3 * (7.0 * t).sin(), 0.5));
            let forward = Vec3::new((9.0 * t).cos(), (9.0 * t).sin(), -0.1);
            View::look(eye, forward, Vec3::Z, 1.0, 16.0 / 9.0)
        })
        .collect();
    // The first query on a thread makes its scratch (the sets on a
    // query's path: notes/query.md); none after.
    pvs.query_view(&views[0], &mut now).unwrap();
    let start = ALLOCATIONS.load(Ordering::Relaxed);
    let mut seen = 0;
    for (k, v) in views.iter().enumerate() {
        pvs.query_view(v, &mut now).unwrap();
        pvs.delta(&before, &now, &mut delta).unwrap();
        seen += delta.entering.count();
        std::mem::swap(&mut now, &mut before);
        pvs.query_view_world(v.position.as_dvec3(), v, &mut now)
            .unwrap();
        let p = v.position;
        let ahead = vis5d::geom::Aabb::new(p - Vec3::splat(0.5), p + Vec3::splat(0.5));
        pvs.query_positions(&ahead, &mut now).unwrap();
        pvs.query_positions_world(DVec3::ZERO, DVec3::ONE, &mut now)
            .unwrap();
        pvs.query_range(&ahead, (-1.0, 2.0), (0.5, 1.5), &mut now)
            .unwrap();
        let q = [p.x, p.y, p.z, -3.0 + 0.01 * k as f32, 1.0];
        pvs.leaf_set(q, &mut now).unwrap();
        pvs.leaf_delta(q, [p.x, p.y, p.z, 0.0, 2.0], &mut delta)
            .unwrap();
    }
    let made = ALLOCATIONS.load(Ordering::Relaxed) - start;
    assert_eq!(made, 0, "{made} allocations in 500 frames");
    assert!(seen > 0);
}
