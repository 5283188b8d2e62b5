//! The C API of the vis5d runtime, for engines written in C or C++.
//!
//! Open a `.v5d` file once ([`vis5d_open_path`] or [`vis5d_open_bytes`]),
//! then per frame answer the camera ([`vis5d_query_camera`], or
//! [`vis5d_query_matrix`] with the view-projection matrix the engine draws
//! with) into a bitset the caller owns: `vis5d_answer_words` 64-bit words,
//! bit `i % 64` of word `i / 64` standing for object `i` (the order of the
//! scene's objects, named by [`vis5d_object_name`]). [`vis5d_delta`] gives
//! the objects entering and leaving between two answers, and
//! [`vis5d_query_box`] everything a box of positions may see (what to
//! stream in before the camera gets there). [`vis5d_free`] releases the
//! file.
//!
//! Every call returns a [`Vis5dStatus`]; on an error,
//! [`vis5d_last_error`] says what went wrong (per thread). No call
//! panics across the boundary (a bug is caught and reported as
//! `VIS5D_STATUS_INTERNAL`), and the queries allocate nothing. A handle
//! may be queried from several threads at once (queries only read it).
//! The header is `include/vis5d.h`; `examples/c/query.c` uses it.

#![warn(missing_docs)]

use std::cell::RefCell;
use std::ffi::{CStr, CString, c_char};
use std::panic::{AssertUnwindSafe, catch_unwind};

use glam::{DVec3, Mat4, Vec3};
use vis5d::query::{Answer, Pvs, View};

/// A loaded `.v5d` file (opaque).
pub struct Vis5dPvs {
    pvs: Pvs,
    /// The objects' names, NUL-terminated (a NUL inside a name ends it).
    names: Vec<CString>,
    /// The objects' ids, NUL-terminated (ids hold no NUL).
    ids: Vec<CString>,
}

/// What a call did.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Vis5dStatus {
    /// Done.
    Ok = 0,
    /// A pointer that must not be null was null.
    NullArgument = 1,
    /// An argument is out of range: not finite, a zero direction, an up
    /// along the forward direction, a field of view outside (0, 180)
    /// degrees, a path that is not UTF-8, a matrix that is not a
    /// perspective projection.
    BadArgument = 2,
    /// The file cannot be read.
    Io = 3,
    /// The bytes are not a valid `.v5d` file (or one this version cannot
    /// read).
    BadFile = 4,
    /// A bitset of another number of words than `vis5d_answer_words`.
    SetSize = 5,
    /// A bug in vis5d, caught: the message says where; please report it.
    Internal = 6,
}

/// How a query was answered.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Vis5dAnswer {
    /// From the tree.
    Tree = 0,
    /// Every object (in the frustum): the eye, or part of the box, lies
    /// outside the view box the tree was built for, where nothing was
    /// sampled. The conservative answer.
    Everything = 1,
}

thread_local! {
    static LAST_ERROR: RefCell<CString> = RefCell::new(CString::default());
}

fn fail(status: Vis5dStatus, message: impl Into<String>) -> Vis5dStatus {
    let text = message.into().replace('\0', " ");
    LAST_ERROR.with(|e| *e.borrow_mut() = CString::new(text).unwrap_or_default());
    status
}

/// Runs `body`, turning a panic into `VIS5D_STATUS_INTERNAL`.
fn guarded(body: impl FnOnce() -> Vis5dStatus) -> Vis5dStatus {
    match catch_unwind(AssertUnwindSafe(body)) {
        Ok(status) => status,
        Err(cause) => {
            let what = cause
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| cause.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "a panic".into());
            fail(Vis5dStatus::Internal, format!("internal error: {what}"))
        }
    }
}

fn answer_of(a: Answer) -> Vis5dAnswer {
    match a {
        Answer::Tree => Vis5dAnswer::Tree,
        _ => Vis5dAnswer::Everything,
    }
}

fn handle(pvs: Pvs) -> *mut Vis5dPvs {
    let names = pvs
        .objects()
        .map(|o| {
            let cut = o.name().split('\0').next().unwrap_or_default();
            CString::new(cut).unwrap_or_default()
        })
        .collect();
    let ids = pvs
        .objects()
        .map(|o| CString::new(o.id()).unwrap_or_default())
        .collect();
    Box::into_raw(Box::new(Vis5dPvs { pvs, names, ids }))
}

/// The message of the last error on this thread (empty before any): a
/// NUL-terminated string, valid until the next failing call on the
/// thread. Never null.
#[unsafe(no_mangle)]
pub extern "C" fn vis5d_last_error() -> *const c_char {
    LAST_ERROR.with(|e| e.borrow().as_ptr())
}

/// The version of vis5d, as "major.minor.patch". Never null.
#[unsafe(no_mangle)]
pub extern "C" fn vis5d_version() -> *const c_char {
    static VERSION: &CStr =
        match CStr::from_bytes_with_nul(concat!(env!("CARGO_PKG_VERSION"), "\0").as_bytes()) {
            Ok(v) => v,
            Err(_) => c"?",
        };
    VERSION.as_ptr()
}

/// Opens the `.v5d` file at `path` (UTF-8, NUL-terminated) into `*out`.
///
/// # Safety
/// `path` is null or a NUL-terminated string; `out` is null or points to
/// a writable pointer.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn vis5d_open_path(
    path: *const c_char,
    out: *mut *mut Vis5dPvs,
) -> Vis5dStatus {
    guarded(|| {
        if path.is_null() || out.is_null() {
            return fail(
                Vis5dStatus::NullArgument,
                "vis5d_open_path: path and out must not be null",
            );
        }
        // SAFETY: non-null and NUL-terminated by the caller's contract.
        let path = unsafe { CStr::from_ptr(path) };
        let Ok(path) = path.to_str() else {
            return fail(
                Vis5dStatus::BadArgument,
                "vis5d_open_path: the path is not UTF-8",
            );
        };
        match Pvs::load(path) {
            Ok(pvs) => {
                // SAFETY: `out` is non-null and writable by contract.
                unsafe { *out = handle(pvs) };
                Vis5dStatus::Ok
            }
            Err(e @ vis5d::query::PvsError::Io { .. }) => fail(Vis5dStatus::Io, e.to_string()),
            Err(e) => fail(Vis5dStatus::BadFile, e.to_string()),
        }
    })
}

/// Opens a `.v5d` file held in memory (`len` bytes at `bytes`, copied:
/// the caller may free them after) into `*out`.
///
/// # Safety
/// `bytes` is null or points to `len` readable bytes; `out` is null or
/// points to a writable pointer.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn vis5d_open_bytes(
    bytes: *const u8,
    len: usize,
    out: *mut *mut Vis5dPvs,
) -> Vis5dStatus {
    guarded(|| {
        if bytes.is_null() || out.is_null() {
            return fail(
                Vis5dStatus::NullArgument,
                "vis5d_open_bytes: bytes and out must not be null",
            );
        }
        // SAFETY: `len` readable bytes by contract.
        let data = unsafe { std::slice::from_raw_parts(bytes, len) };
        match Pvs::from_bytes(data) {
            Ok(pvs) => {
                // SAFETY: `out` is non-null and writable by contract.
                unsafe { *out = handle(pvs) };
                Vis5dStatus::Ok
            }
            Err(e) => fail(Vis5dStatus::BadFile, format!("the .v5d bytes: {e}")),
        }
    })
}

/// Releases a file opened by `vis5d_open_*` (null: nothing).
///
/// # Safety
/// `pvs` is null or a handle from `vis5d_open_*` not yet freed; no other
/// thread uses it during or after the call.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn vis5d_free(pvs: *mut Vis5dPvs) {
    if !pvs.is_null() {
        // SAFETY: made by Box::into_raw in `handle`, freed once.
        drop(unsafe { Box::from_raw(pvs) });
    }
}

/// The number of objects (0 for null).
///
/// # Safety
/// `pvs` is null or a live handle.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn vis5d_object_count(pvs: *const Vis5dPvs) -> usize {
    // SAFETY: null or live by contract.
    unsafe { pvs.as_ref() }.map_or(0, |h| h.pvs.object_count())
}

/// The number of 64-bit words of an answer bitset (0 for null).
///
/// # Safety
/// `pvs` is null or a live handle.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn vis5d_answer_words(pvs: *const Vis5dPvs) -> usize {
    // SAFETY: null or live by contract.
    unsafe { pvs.as_ref() }.map_or(0, |h| h.pvs.answer_words())
}

/// The name of object `object` (NUL-terminated, valid while the handle
/// lives); null for an index past the count or a null handle.
///
/// # Safety
/// `pvs` is null or a live handle.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn vis5d_object_name(pvs: *const Vis5dPvs, object: usize) -> *const c_char {
    // SAFETY: null or live by contract.
    unsafe { pvs.as_ref() }
        .and_then(|h| h.names.get(object))
        .map_or(std::ptr::null(), |n| n.as_ptr())
}

/// The box of eye positions the tree was built for, in world
/// coordinates, into `min` and `max` (three doubles each): eyes outside
/// it are answered with every object.
///
/// # Safety
/// `pvs` is null or a live handle; `min` and `max` are null or point to
/// three writable doubles.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn vis5d_view_box(
    pvs: *const Vis5dPvs,
    min: *mut f64,
    max: *mut f64,
) -> Vis5dStatus {
    guarded(|| {
        // SAFETY: null or live by contract.
        let Some(h) = (unsafe { pvs.as_ref() }) else {
            return fail(Vis5dStatus::NullArgument, "vis5d_view_box: pvs is null");
        };
        if min.is_null() || max.is_null() {
            return fail(
                Vis5dStatus::NullArgument,
                "vis5d_view_box: min and max must not be null",
            );
        }
        let (lo, hi) = h.pvs.frame().box_to_world(&h.pvs.view_box());
        for k in 0..3 {
            // SAFETY: three writable doubles each by contract.
            unsafe {
                *min.add(k) = lo[k];
                *max.add(k) = hi[k];
            }
        }
        Vis5dStatus::Ok
    })
}

/// The scene's up direction in world coordinates (the axis the tree was
/// built with, `vis5d build --up`), into `up` (three floats: one 1, two
/// 0).
///
/// # Safety
/// `pvs` is null or a live handle; `up` is null or points to three
/// writable floats.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn vis5d_up(pvs: *const Vis5dPvs, up: *mut f32) -> Vis5dStatus {
    guarded(|| {
        // SAFETY: null or live by contract.
        let Some(h) = (unsafe { pvs.as_ref() }) else {
            return fail(Vis5dStatus::NullArgument, "vis5d_up: pvs is null");
        };
        if up.is_null() {
            return fail(Vis5dStatus::NullArgument, "vis5d_up: up must not be null");
        }
        let v = h.pvs.frame().up.world_vector();
        for k in 0..3 {
            // SAFETY: three writable floats by contract.
            unsafe { *up.add(k) = v[k] };
        }
        Vis5dStatus::Ok
    })
}

/// The id of object `object`: unique in the file (its name, `name#k`
/// where names repeat, the model's own (a glTF node's
/// `extras.vis5d.id`), or the id the build's `--ids` gave it);
/// NUL-terminated, valid while the handle lives; null for an index past
/// the count or a null handle.
///
/// # Safety
/// `pvs` is null or a live handle.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn vis5d_object_id(pvs: *const Vis5dPvs, object: usize) -> *const c_char {
    // SAFETY: null or live by contract.
    unsafe { pvs.as_ref() }
        .and_then(|h| h.ids.get(object))
        .map_or(std::ptr::null(), |n| n.as_ptr())
}

/// Object flag: in every set of the tree (a sky, what must never be
/// culled; a glTF node's `extras.vis5d.flags`, `vis5d build --flags`).
pub const VIS5D_FLAG_ALWAYS_VISIBLE: u8 = 1;

/// Object flag: hides nothing, rays pass through it (glass, foliage).
pub const VIS5D_FLAG_NEVER_OCCLUDER: u8 = 2;

// The header's literals are the library's bits.
const _: () = assert!(
    VIS5D_FLAG_ALWAYS_VISIBLE == vis5d::codec::ObjectFlags::ALWAYS_VISIBLE.bits()
        && VIS5D_FLAG_NEVER_OCCLUDER == vis5d::codec::ObjectFlags::NEVER_OCCLUDER.bits()
);

/// The flags of object `object` as the build set them: a combination of
/// `VIS5D_FLAG_ALWAYS_VISIBLE` and `VIS5D_FLAG_NEVER_OCCLUDER`; 0 for
/// none, for an index past the count or for a null handle.
///
/// # Safety
/// `pvs` is null or a live handle.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn vis5d_object_flags(pvs: *const Vis5dPvs, object: usize) -> u8 {
    // SAFETY: null or live by contract.
    unsafe { pvs.as_ref() }
        .and_then(|h| h.pvs.object(object))
        .map_or(0, |o| o.flags().bits())
}

/// The index of the object whose id is `id` (NUL-terminated UTF-8) into
/// `*object`; `VIS5D_STATUS_BAD_ARGUMENT` when no object has it.
///
/// # Safety
/// `pvs` is null or a live handle; `id` is null or NUL-terminated;
/// `object` is null or writable.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn vis5d_object_index(
    pvs: *const Vis5dPvs,
    id: *const c_char,
    object: *mut usize,
) -> Vis5dStatus {
    guarded(|| {
        // SAFETY: null or live by contract.
        let Some(h) = (unsafe { pvs.as_ref() }) else {
            return fail(Vis5dStatus::NullArgument, "vis5d_object_index: pvs is null");
        };
        if id.is_null() || object.is_null() {
            return fail(
                Vis5dStatus::NullArgument,
                "vis5d_object_index: id and object must not be null",
            );
        }
        // SAFETY: NUL-terminated by contract.
        let text = unsafe { CStr::from_ptr(id) }.to_string_lossy();
        match h.pvs.object_index(&text) {
            Some(i) => {
                // SAFETY: non-null and writable by contract.
                unsafe { *object = i };
                Vis5dStatus::Ok
            }
            None => fail(
                Vis5dStatus::BadArgument,
                format!("vis5d_object_index: no object has the id {text:?}"),
            ),
        }
    })
}

/// Reads three values.
///
/// # Safety
/// `p` is non-null and points to three readable values.
unsafe fn three<T: Copy>(p: *const T) -> [T; 3] {
    // SAFETY: by the caller's contract.
    unsafe { [*p, *p.add(1), *p.add(2)] }
}

/// The answer bitset as a slice, checked against the file.
///
/// # Safety
/// `set` is non-null and points to `words` writable words.
unsafe fn answer_slice<'a>(
    h: &Vis5dPvs,
    set: *mut u64,
    words: usize,
) -> Result<&'a mut [u64], Vis5dStatus> {
    if words != h.pvs.answer_words() {
        return Err(fail(
            Vis5dStatus::SetSize,
            format!(
                "the bitset has {words} words, the file's answers {} (vis5d_answer_words)",
                h.pvs.answer_words()
            ),
        ));
    }
    // SAFETY: by the caller's contract.
    Ok(unsafe { std::slice::from_raw_parts_mut(set, words) })
}

/// Runs `query` into the caller's bitset (checked against the file) and
/// says how it answered.
///
/// # Safety
/// `set` is non-null and points to `words` writable words; `answer` is
/// null or writable.
unsafe fn answer_into(
    h: &Vis5dPvs,
    set: *mut u64,
    words: usize,
    answer: *mut Vis5dAnswer,
    query: impl FnOnce(&Pvs, &mut [u64]) -> Result<Answer, vis5d::query::SetSizeError>,
) -> Vis5dStatus {
    // SAFETY: by the caller's contract.
    let out = match unsafe { answer_slice(h, set, words) } {
        Ok(out) => out,
        Err(status) => return status,
    };
    match query(&h.pvs, out) {
        Ok(a) => {
            // SAFETY: null or writable by the caller's contract.
            unsafe { tell(answer, a) };
            Vis5dStatus::Ok
        }
        Err(e) => fail(Vis5dStatus::SetSize, e.to_string()),
    }
}

/// The world view `view` from the world eye `eye`, answered into the
/// caller's bitset.
///
/// # Safety
/// As [`answer_into`].
unsafe fn view_into(
    h: &Vis5dPvs,
    eye: DVec3,
    view: &View,
    set: *mut u64,
    words: usize,
    answer: *mut Vis5dAnswer,
) -> Vis5dStatus {
    let frame = h.pvs.frame();
    let positions = frame.box_to_local(eye, eye);
    let local = view.to_local(&frame, eye);
    // SAFETY: by the caller's contract.
    unsafe {
        answer_into(h, set, words, answer, |pvs, out| {
            pvs.query_view_from_words(&positions, &local, out)
        })
    }
}

/// Writes `answer` where the caller asked for it.
///
/// # Safety
/// `out` is null or writable.
unsafe fn tell(out: *mut Vis5dAnswer, answer: Answer) {
    if !out.is_null() {
        // SAFETY: non-null and writable by contract.
        unsafe { *out = answer_of(answer) };
    }
}

/// The objects a camera may see, into the caller's bitset `set` of
/// `words` words (`vis5d_answer_words`): from `eye` (world coordinates,
/// three doubles) looking along `forward` with `up` (three floats each,
/// world axes, any length; `up` not along `forward`), a vertical field of
/// view of `vfov_degrees` and a width over height of `aspect`. `*answer`
/// (when not null) says whether the tree answered or the eye lay outside
/// its view box (every object in the frustum).
///
/// # Safety
/// `pvs` is null or a live handle; `eye`, `forward` and `up` are null or
/// point to three values; `set` is null or points to `words` writable
/// words; `answer` is null or writable.
#[unsafe(no_mangle)]
#[allow(clippy::too_many_arguments)]
pub unsafe extern "C" fn vis5d_query_camera(
    pvs: *const Vis5dPvs,
    eye: *const f64,
    forward: *const f32,
    up: *const f32,
    vfov_degrees: f32,
    aspect: f32,
    set: *mut u64,
    words: usize,
    answer: *mut Vis5dAnswer,
) -> Vis5dStatus {
    guarded(|| {
        // SAFETY: null or live by contract.
        let Some(h) = (unsafe { pvs.as_ref() }) else {
            return fail(Vis5dStatus::NullArgument, "vis5d_query_camera: pvs is null");
        };
        if eye.is_null() || forward.is_null() || up.is_null() || set.is_null() {
            return fail(
                Vis5dStatus::NullArgument,
                "vis5d_query_camera: eye, forward, up and set must not be null",
            );
        }
        // SAFETY: three readable values each, by contract.
        let (e, f, u) = unsafe { (three(eye), three(forward), three(up)) };
        let (eye, forward, up) = (DVec3::from(e), Vec3::from(f), Vec3::from(u));
        let view = View::look(
            eye.as_vec3(),
            forward,
            up,
            vfov_degrees.to_radians(),
            aspect,
        );
        let ok = eye.is_finite()
            && forward.is_finite()
            && forward != Vec3::ZERO
            && up.is_finite()
            && up.cross(forward).length() > 1e-6 * up.length() * forward.length()
            && vfov_degrees > 0.0
            && vfov_degrees < 180.0
            && aspect.is_finite()
            && aspect > 0.0
            && view.fov_x < std::f32::consts::PI;
        if !ok {
            return fail(
                Vis5dStatus::BadArgument,
                format!(
                    "vis5d_query_camera: eye {eye}, forward {forward}, up {up}, vfov {vfov_degrees}, aspect {aspect}: \
                     need finite values, a non-zero forward, an up not along it, 0 < vfov < 180 and a horizontal field under 180 degrees"
                ),
            );
        }
        // SAFETY: `words` writable words by contract.
        // SAFETY: `words` writable words and `answer` null or writable,
        // by contract.
        unsafe { view_into(h, eye, &view, set, words, answer) }
    })
}

/// As `vis5d_query_camera`, the camera given by the view-projection
/// matrix the engine draws with (`clip = m * world`, 16 floats in
/// column-major order, as OpenGL, Vulkan, Direct3D with column vectors
/// and glm hold it; any depth range, handedness or y direction).
/// `VIS5D_STATUS_BAD_ARGUMENT` for a matrix that is not a perspective
/// projection. World coordinates in f32: for a scene far from the origin
/// use `vis5d_query_camera`, whose eye is in doubles.
///
/// # Safety
/// `pvs` is null or a live handle; `view_projection` is null or points to
/// 16 floats; `set` is null or points to `words` writable words; `answer`
/// is null or writable.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn vis5d_query_matrix(
    pvs: *const Vis5dPvs,
    view_projection: *const f32,
    set: *mut u64,
    words: usize,
    answer: *mut Vis5dAnswer,
) -> Vis5dStatus {
    guarded(|| {
        // SAFETY: null or live by contract.
        let Some(h) = (unsafe { pvs.as_ref() }) else {
            return fail(Vis5dStatus::NullArgument, "vis5d_query_matrix: pvs is null");
        };
        if view_projection.is_null() || set.is_null() {
            return fail(
                Vis5dStatus::NullArgument,
                "vis5d_query_matrix: view_projection and set must not be null",
            );
        }
        // SAFETY: 16 readable floats by contract.
        let m: [f32; 16] = unsafe { std::ptr::read_unaligned(view_projection.cast()) };
        let Some(view) = View::from_view_projection(Mat4::from_cols_array(&m)) else {
            return fail(
                Vis5dStatus::BadArgument,
                "vis5d_query_matrix: the matrix is not a perspective projection with a field of view under 180 degrees",
            );
        };
        // SAFETY: `words` writable words by contract.
        // SAFETY: `words` writable words and `answer` null or writable,
        // by contract.
        unsafe { view_into(h, view.position.as_dvec3(), &view, set, words, answer) }
    })
}

/// Every object visible from some point of the box `[min, max]` (world
/// coordinates, three doubles each) in any direction, into `set`: what to
/// stream in before the camera enters the box. `*answer` is
/// `VIS5D_ANSWER_EVERYTHING` when the box reaches outside the view box.
///
/// # Safety
/// `pvs` is null or a live handle; `min` and `max` are null or point to
/// three doubles; `set` is null or points to `words` writable words;
/// `answer` is null or writable.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn vis5d_query_box(
    pvs: *const Vis5dPvs,
    min: *const f64,
    max: *const f64,
    set: *mut u64,
    words: usize,
    answer: *mut Vis5dAnswer,
) -> Vis5dStatus {
    guarded(|| {
        // SAFETY: null or live by contract.
        let Some(h) = (unsafe { pvs.as_ref() }) else {
            return fail(Vis5dStatus::NullArgument, "vis5d_query_box: pvs is null");
        };
        if min.is_null() || max.is_null() || set.is_null() {
            return fail(
                Vis5dStatus::NullArgument,
                "vis5d_query_box: min, max and set must not be null",
            );
        }
        // SAFETY: three readable doubles each by contract.
        let (lo, hi) = unsafe { (DVec3::from(three(min)), DVec3::from(three(max))) };
        if !(lo.is_finite() && hi.is_finite() && lo.cmple(hi).all()) {
            return fail(
                Vis5dStatus::BadArgument,
                format!("vis5d_query_box: the box {lo} .. {hi} is not finite with min <= max"),
            );
        }
        // SAFETY: `words` writable words by contract.
        let local = h.pvs.frame().box_to_local(lo, hi);
        let pi = std::f32::consts::PI;
        // SAFETY: `words` writable words and `answer` null or writable,
        // by contract.
        unsafe {
            answer_into(h, set, words, answer, |pvs, out| {
                pvs.query_range_words(&local, (-pi, pi), (0.0, pi), out)
            })
        }
    })
}

/// The change from the answer `from` to the answer `to` (bitsets of
/// `words` words): `entering = to & ~from`, `leaving = from & ~to`.
///
/// # Safety
/// `pvs` is null or a live handle; `from` and `to` are null or point to
/// `words` readable words, `entering` and `leaving` to `words` writable
/// ones (none overlapping the others).
#[unsafe(no_mangle)]
pub unsafe extern "C" fn vis5d_delta(
    pvs: *const Vis5dPvs,
    from: *const u64,
    to: *const u64,
    entering: *mut u64,
    leaving: *mut u64,
    words: usize,
) -> Vis5dStatus {
    guarded(|| {
        // SAFETY: null or live by contract.
        let Some(h) = (unsafe { pvs.as_ref() }) else {
            return fail(Vis5dStatus::NullArgument, "vis5d_delta: pvs is null");
        };
        if from.is_null() || to.is_null() || entering.is_null() || leaving.is_null() {
            return fail(
                Vis5dStatus::NullArgument,
                "vis5d_delta: the bitsets must not be null",
            );
        }
        if words != h.pvs.answer_words() {
            return fail(
                Vis5dStatus::SetSize,
                format!(
                    "vis5d_delta: {words} words, the file's answers have {}",
                    h.pvs.answer_words()
                ),
            );
        }
        // SAFETY: `words` words each, not overlapping, by contract.
        let (a, b, e, l) = unsafe {
            (
                std::slice::from_raw_parts(from, words),
                std::slice::from_raw_parts(to, words),
                std::slice::from_raw_parts_mut(entering, words),
                std::slice::from_raw_parts_mut(leaving, words),
            )
        };
        for k in 0..words {
            e[k] = b[k] & !a[k];
            l[k] = a[k] & !b[k];
        }
        Vis5dStatus::Ok
    })
}
