//! `include/glint.h` is what cbindgen generates from this crate with `cbindgen.toml`.

use std::path::Path;

#[test]
fn header_is_current() {
    let crate_dir = Path::new(env!("CARGO_MANIFEST_DIR"));
    let config = cbindgen::Config::from_file(crate_dir.join("cbindgen.toml"))
        .expect("cbindgen.toml is valid");
    let bindings = cbindgen::Builder::new()
        .with_config(config)
        .with_src(crate_dir.join("src/lib.rs"))
        .generate()
        .expect("cbindgen parses the crate");
    let mut generated = Vec::new();
    bindings.write(&mut generated);
    let generated = String::from_utf8(generated).expect("cbindgen writes UTF-8");

    let path = crate_dir.join("include/glint.h");
    if std::env::var_os("GLINT_BLESS").is_some() {
        std::fs::write(&path, &generated).expect("include/glint.h is writable");
        return;
    }
    let committed = std::fs::read_to_string(&path).unwrap_or_default();
    if committed != generated {
        let line = committed
            .lines()
            .zip(generated.lines())
            .position(|(a, b)| a != b)
            .unwrap_or_else(|| committed.lines().count().min(generated.lines().count()));
        panic!(
            "crates/capi/include/glint.h is not what cbindgen generates from the crate (first \
             difference at line {}: {:?} generated, {:?} committed); regenerate it with\n    \
             GLINT_BLESS=1 cargo test -p glint-capi --test header\nand commit it",
            line + 1,
            generated.lines().nth(line).unwrap_or("<end>"),
            committed.lines().nth(line).unwrap_or("<end>"),
        );
    }
}
