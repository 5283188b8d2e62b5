//! `include/vis5d.h` is what cbindgen makes of `capi/src/lib.rs` today:
//! regenerated here and compared byte for byte (`VIS5D_BLESS=1` writes
//! it instead, after a change to the API).

use std::path::Path;

#[test]
fn the_committed_header_is_up_to_date() {
    let crate_dir = Path::new(env!("CARGO_MANIFEST_DIR"));
    let config =
        cbindgen::Config::from_file(crate_dir.join("cbindgen.toml")).expect("cbindgen.toml");
    let mut generated = Vec::new();
    cbindgen::Builder::new()
        .with_crate(crate_dir)
        .with_config(config)
        .generate()
        .expect("cbindgen reads capi/src/lib.rs")
        .write(&mut generated);
    let header = crate_dir.join("../include/vis5d.h");
    if std::env::var_os("VIS5D_BLESS").is_some() {
        std::fs::write(&header, &generated).unwrap();
        return;
    }
    let committed = std::fs::read(&header).unwrap_or_default();
    assert!(
        committed == generated,
        "include/vis5d.h is out of date with capi/src/lib.rs: run \
         `VIS5D_BLESS=1 cargo test -p vis5d-capi --test header` and commit it"
    );
}
