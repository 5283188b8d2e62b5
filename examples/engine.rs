//! What an engine does with a `.v5d` file, using only the runtime API
//! (`vis5d = { default-features = false }`): load it once, then per frame
//! ask for the potentially visible set of the camera, take the change from
//! the last frame (objects to start and stop drawing), and prefetch what
//! the box of positions ahead of the camera may see.
//!
//! ```text
//! vis5d build scenes/apartment.obj -o apartment.v5d
//! cargo run --release --example engine -- apartment.v5d [FRAMES]
//! ```
//!
//! The camera walks a loop through the middle of the tree's view box,
//! looking along its path (60 degrees vertical, 16:9), up the file's up
//! axis.

use std::process::ExitCode;
use std::time::Instant;

use glam::{DVec3, Vec3};
use vis5d::{Answer, Pvs, View};

fn main() -> ExitCode {
    let mut args = std::env::args().skip(1);
    let (Some(path), frames) = (args.next(), args.next()) else {
        eprintln!("usage: engine FILE.v5d [FRAMES]");
        return ExitCode::from(2);
    };
    let frames: usize = match frames.map(|f| f.parse()) {
        None => 1000,
        Some(Ok(n)) if n > 0 => n,
        Some(_) => {
            eprintln!("FRAMES must be a positive whole number");
            return ExitCode::from(2);
        }
    };
    // Once: load, make the answer sets and the delta.
    let pvs = match Pvs::load(&path) {
        Ok(pvs) => pvs,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::from(2);
        }
    };
    let (mut visible, mut last, mut ahead) = (pvs.new_set(), pvs.new_set(), pvs.new_set());
    let mut delta = pvs.new_delta();
    let frame = pvs.frame();
    let up = frame.dir_to_world(Vec3::Z);
    let (lo, hi) = frame.box_to_world(&pvs.view_box());
    let (centre, size) = ((lo + hi) * 0.5, hi - lo);
    // The camera's path, in world coordinates: an ellipse through the
    // middle of the view box, in the plane across the up axis.
    let across = |k: usize| {
        let a = frame.dir_to_world(Vec3::X).as_dvec3();
        let b = frame.dir_to_world(Vec3::Y).as_dvec3();
        let t = std::f64::consts::TAU * k as f64 / frames as f64;
        centre + 0.35 * (a * a.dot(size) * t.cos() + b * b.dot(size) * t.sin())
    };
    let (mut answer_sum, mut entering, mut leaving, mut outside) = (0, 0, 0, 0);
    let (mut prefetched, mut query_seconds) = (0, 0.0);
    for k in 0..frames {
        let eye: DVec3 = across(k);
        let forward = (across(k + 1) - eye).as_vec3();
        let view = View::look(eye.as_vec3(), forward, up, 60f32.to_radians(), 16.0 / 9.0);
        let start = Instant::now();
        let answer = pvs
            .query_view_world(eye, &view, &mut visible)
            .expect("the sets were made by new_set");
        query_seconds += start.elapsed().as_secs_f64();
        outside += usize::from(answer == Answer::Everything);
        answer_sum += visible.count();
        // The change since the last frame: upload or start drawing the
        // entering objects, release the leaving ones.
        pvs.delta(&last, &visible, &mut delta)
            .expect("the sets were made by new_set");
        entering += delta.entering.count();
        leaving += delta.leaving.count();
        std::mem::swap(&mut last, &mut visible);
        // Every 50 frames: what the next stretch of path may see, from a
        // 2 m box around the eye 50 frames on.
        if k % 50 == 0 {
            let next = across(k + 50);
            pvs.query_positions_world(next - 1.0, next + 1.0, &mut ahead)
                .expect("the sets were made by new_set");
            prefetched += ahead.count();
        }
    }
    let n = pvs.object_count();
    println!(
        "{path}: {n} objects, {} nodes, {} bytes in memory",
        pvs.node_count(),
        pvs.memory_bytes()
    );
    println!(
        "{frames} frames: {:.1} objects a frame ({:.1}% of the scene), {:.2} entering and {:.2} leaving a frame, {:.1} objects prefetched a box, {:.2} us a query{}",
        answer_sum as f64 / frames as f64,
        100.0 * answer_sum as f64 / (frames * n.max(1)) as f64,
        entering as f64 / frames as f64,
        leaving as f64 / frames as f64,
        prefetched as f64 / frames.div_ceil(50) as f64,
        1e6 * query_seconds / frames as f64,
        if outside > 0 {
            format!("; {outside} frames outside the view box (every object)")
        } else {
            String::new()
        }
    );
    ExitCode::SUCCESS
}
