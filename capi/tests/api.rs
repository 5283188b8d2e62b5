//! The C API from Rust: bad arguments are refused with a status and a
//! message, never a crash; answers equal the Rust API's.

use std::ffi::{CStr, CString};
use std::ptr;

use vis5d_c::*;

mod common;

fn last_error() -> String {
    // SAFETY: never null, NUL-terminated.
    unsafe { CStr::from_ptr(vis5d_last_error()) }
        .to_string_lossy()
        .into_owned()
}

#[test]
fn bad_arguments_are_refused_and_answers_match_the_rust_api() {
    let bytes = common::small_file(6);
    let mut pvs = ptr::null_mut();
    // SAFETY: valid pointers throughout; the handle is freed once.
    unsafe {
        assert_eq!(
            vis5d_open_bytes(bytes.as_ptr(), bytes.len(), &mut pvs),
            Vis5dStatus::Ok
        );
        let words = vis5d_answer_words(pvs);
        let n = vis5d_object_count(pvs);
        assert_eq!(words, n.div_ceil(64));
        let mut set = vec![0u64; words];
        let mut answer = Vis5dAnswer::Everything;
        let (eye, fwd, up) = ([3.0f64, 2.5, 1.5], [1.0f32, 0.2, 0.0], [0.0f32, 0.0, 1.0]);
        let q = |set: &mut [u64],
                 eye: &[f64; 3],
                 fwd: &[f32; 3],
                 up: &[f32; 3],
                 vfov,
                 aspect,
                 answer: *mut Vis5dAnswer| {
            vis5d_query_camera(
                pvs,
                eye.as_ptr(),
                fwd.as_ptr(),
                up.as_ptr(),
                vfov,
                aspect,
                set.as_mut_ptr(),
                set.len(),
                answer,
            )
        };
        assert_eq!(
            q(&mut set, &eye, &fwd, &up, 60.0, 1.5, &mut answer),
            Vis5dStatus::Ok
        );
        assert_eq!(answer, Vis5dAnswer::Tree);
        // The same answer from the Rust API.
        let rust = vis5d::query::Pvs::from_bytes(&bytes).unwrap();
        let mut want = rust.new_set();
        let view = vis5d::query::View::look(
            glam::Vec3::ZERO,
            glam::Vec3::from(fwd),
            glam::Vec3::from(up),
            60f32.to_radians(),
            1.5,
        );
        rust.query_view_world(glam::DVec3::from(eye), &view, &mut want)
            .unwrap();
        assert_eq!(set, want.words());
        // Outside the view box: every object in the frustum, and said.
        let far = [1e4, 2.5, 1.5];
        assert_eq!(
            q(
                &mut set,
                &far,
                &[-1.0, 0.0, 0.0],
                &up,
                60.0,
                1.5,
                &mut answer
            ),
            Vis5dStatus::Ok
        );
        assert_eq!(answer, Vis5dAnswer::Everything);
        // Refused: wrong sizes, nulls, bad numbers; the set untouched.
        let before = set.clone();
        let mut big = vec![0u64; words + 1];
        assert_eq!(
            q(&mut big, &eye, &fwd, &up, 60.0, 1.5, ptr::null_mut()),
            Vis5dStatus::SetSize
        );
        assert!(
            last_error().contains("vis5d_answer_words"),
            "{}",
            last_error()
        );
        for (vfov, aspect, fwd, up) in [
            (0.0, 1.0, fwd, up),
            (180.0, 1.0, fwd, up),
            (f32::NAN, 1.0, fwd, up),
            (60.0, 0.0, fwd, up),
            (60.0, 1e9, fwd, up),
            (60.0, 1.0, [0.0; 3], up),
            (60.0, 1.0, fwd, fwd),
            (60.0, 1.0, [f32::INFINITY, 0.0, 0.0], up),
        ] {
            assert_eq!(
                q(&mut set, &eye, &fwd, &up, vfov, aspect, ptr::null_mut()),
                Vis5dStatus::BadArgument,
                "{vfov} {aspect} {fwd:?} {up:?}"
            );
        }
        assert_eq!(set, before);
        assert_eq!(
            vis5d_query_camera(
                ptr::null(),
                eye.as_ptr(),
                fwd.as_ptr(),
                up.as_ptr(),
                60.0,
                1.0,
                set.as_mut_ptr(),
                words,
                ptr::null_mut()
            ),
            Vis5dStatus::NullArgument
        );
        assert_eq!(
            vis5d_query_camera(
                pvs,
                ptr::null(),
                fwd.as_ptr(),
                up.as_ptr(),
                60.0,
                1.0,
                set.as_mut_ptr(),
                words,
                ptr::null_mut()
            ),
            Vis5dStatus::NullArgument
        );
        let ortho = [
            1.0f32, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, -0.1, 0.0, 0.0, 0.0, -0.01, 1.0,
        ];
        assert_eq!(
            vis5d_query_matrix(
                pvs,
                ortho.as_ptr(),
                set.as_mut_ptr(),
                words,
                ptr::null_mut()
            ),
            Vis5dStatus::BadArgument
        );
        let (lo, hi) = ([1.0f64, 1.0, 1.0], [0.0f64, 2.0, 2.0]);
        assert_eq!(
            vis5d_query_box(
                pvs,
                lo.as_ptr(),
                hi.as_ptr(),
                set.as_mut_ptr(),
                words,
                ptr::null_mut()
            ),
            Vis5dStatus::BadArgument
        );
        // Names, the view box, the up axis.
        assert!(vis5d_object_name(pvs, n).is_null());
        assert!(vis5d_object_id(pvs, n).is_null());
        for o in [0, n / 2, n - 1] {
            let id = CStr::from_ptr(vis5d_object_id(pvs, o));
            assert_eq!(id.to_str().unwrap(), rust.object(o).unwrap().id());
            let mut found = usize::MAX;
            assert_eq!(
                vis5d_object_index(pvs, id.as_ptr(), &mut found),
                Vis5dStatus::Ok
            );
            assert_eq!(found, o);
        }
        let nobody = CString::new("no such object").unwrap();
        let mut found = 0;
        assert_eq!(
            vis5d_object_index(pvs, nobody.as_ptr(), &mut found),
            Vis5dStatus::BadArgument
        );
        let name = CStr::from_ptr(vis5d_object_name(pvs, 0)).to_str().unwrap();
        assert_eq!(name, rust.object(0).unwrap().name());
        // Flags as the build set them (common::small_file).
        assert_eq!(vis5d_object_flags(pvs, 0), VIS5D_FLAG_NEVER_OCCLUDER);
        assert_eq!(vis5d_object_flags(pvs, n - 1), VIS5D_FLAG_ALWAYS_VISIBLE);
        assert_eq!(vis5d_object_flags(pvs, 1), 0);
        assert_eq!(vis5d_object_flags(pvs, n), 0);
        assert_eq!(vis5d_object_flags(ptr::null(), 0), 0);
        let (mut bmin, mut bmax, mut upv) = ([0f64; 3], [0f64; 3], [0f32; 3]);
        assert_eq!(
            vis5d_view_box(pvs, bmin.as_mut_ptr(), bmax.as_mut_ptr()),
            Vis5dStatus::Ok
        );
        assert!(bmin[0] < bmax[0]);
        assert_eq!(vis5d_up(pvs, upv.as_mut_ptr()), Vis5dStatus::Ok);
        assert_eq!(upv, [0.0, 0.0, 1.0]);
        vis5d_free(pvs);
        vis5d_free(ptr::null_mut());
        // Files: damaged bytes, a missing path, a path that is not UTF-8.
        let mut bad = bytes.clone();
        bad[40] ^= 1;
        let mut h = ptr::null_mut();
        assert_eq!(
            vis5d_open_bytes(bad.as_ptr(), bad.len(), &mut h),
            Vis5dStatus::BadFile
        );
        assert!(
            h.is_null() && last_error().contains("damaged"),
            "{}",
            last_error()
        );
        let missing = CString::new("/nonexistent/x.v5d").unwrap();
        assert_eq!(vis5d_open_path(missing.as_ptr(), &mut h), Vis5dStatus::Io);
        assert!(
            last_error().contains("/nonexistent/x.v5d"),
            "{}",
            last_error()
        );
        let not_utf8 = CString::new(vec![0xffu8, 0xfe]).unwrap();
        assert_eq!(
            vis5d_open_path(not_utf8.as_ptr(), &mut h),
            Vis5dStatus::BadArgument
        );
        assert_eq!(
            vis5d_open_path(ptr::null(), &mut h),
            Vis5dStatus::NullArgument
        );
        assert!(!CStr::from_ptr(vis5d_version()).to_bytes().is_empty());
    }
}
