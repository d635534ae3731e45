//! `include/mcdenoise.h` is the header cbindgen generates from
//! `capi/src/lib.rs` (in `capi/build.rs`): it must be current. To update it:
//! `MCDENOISE_BLESS=1 cargo test -p mcdenoise-capi --test header`.

use std::path::Path;

#[test]
fn committed_header_is_current() {
    let generated = include_str!(concat!(env!("OUT_DIR"), "/mcdenoise.h"));
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../include/mcdenoise.h");
    if std::env::var("MCDENOISE_BLESS").is_ok_and(|v| v == "1") {
        std::fs::write(&path, generated).unwrap();
    }
    let committed = std::fs::read_to_string(&path).unwrap_or_default();
    assert!(
        committed == generated,
        "include/mcdenoise.h is not the header capi/build.rs generates; run \
         MCDENOISE_BLESS=1 cargo test -p mcdenoise-capi --test header and commit it"
    );
}
