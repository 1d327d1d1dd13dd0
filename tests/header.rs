//! The committed C header must equal what cbindgen generates from src/ffi.
//! Regenerate with `HOCURVE_UPDATE_HEADER=1 cargo test --test header`.

#[test]
fn committed_header_matches_cbindgen_output() {
    let root = env!("CARGO_MANIFEST_DIR");
    let config =
        cbindgen::Config::from_file(format!("{root}/cbindgen.toml")).expect("cbindgen.toml");
    let bindings = cbindgen::Builder::new()
        .with_crate(root)
        .with_config(config)
        .generate()
        .expect("cbindgen failed");
    let mut generated = Vec::new();
    bindings.write(&mut generated);
    let generated = String::from_utf8(generated).unwrap();
    for line in generated.lines().filter(|l| l.starts_with("#define")) {
        assert!(
            line.starts_with("#define HOC"),
            "non-ABI constant in the header (exclude it in cbindgen.toml): {line}"
        );
    }
    let path = format!("{root}/include/hocurve.h");
    if std::env::var_os("HOCURVE_UPDATE_HEADER").is_some() {
        std::fs::write(&path, &generated).unwrap();
    }
    let committed = std::fs::read_to_string(&path).unwrap_or_default();
    assert!(
        committed == generated,
        "include/hocurve.h is stale: run `HOCURVE_UPDATE_HEADER=1 cargo test --test header` and commit it"
    );
}
