//! What the C API's tests share.

/// A `.v5d` file of the procedural apartment, its tree cut at `max_depth`;
/// its first object never occludes, its last is always visible.
pub fn small_file(max_depth: u32) -> Vec<u8> {
    use vis5d::scene::ObjectFlags;
    use vis5d::scene::procedural::{SceneKind, generate};
    let scene = generate(SceneKind::Apartment, 1, 1);
    let mut flags = vec![ObjectFlags::NONE; scene.objects().len()];
    flags[0] = ObjectFlags::NEVER_OCCLUDER;
    *flags.last_mut().unwrap() = ObjectFlags::ALWAYS_VISIBLE;
    let scene = scene.with_flags(&flags);
    let tracer = vis5d::trace::Tracer::new(&scene);
    let params = vis5d::builder::BuildParams {
        max_depth,
        ..Default::default()
    };
    let (tree, _) = vis5d::builder::build(&scene, &tracer, &params, &|_| {}).unwrap();
    vis5d::codec::write_file(&vis5d::builder::to_file(&scene, tree, &params, None))
}
