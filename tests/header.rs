//! The committed C header must equal what cbindgen generates from src/ffi.
//! Regenerate with `HOCURVE_UPDATE_HEADER=1 cargo test --test header`.

#[test]
fn committed_header_matches_cbindgen_output() {
    let root = env!("CARGO_MANIFEST_DIR");
    let config = cbindgen::Config::from_file(format!("{root}/cbindgen.toml")).expect("cbindgen.toml");
    let bindings = cbindgen::Builder::new().with_crate(root).with_config(config).generate().expect("cbindgen failed");
    let mut generated = Vec::new();
    bindings.write(&mut generated);
    let generated = String::from_utf8(generated).unwrap();
    for line in generated.lines().filter(|l| l.starts_with("#define")) {
        assert!(
            line.starts_with("#define HOC"),
            "non-ABI constant in the header (exclude it in cbindgen.toml): {line}"
        );
    }
    for name in declared_names(&generated) {
        assert!(
            ["Hoc", "HOC_", "HOCURVE_", "hoc_"].iter().any(|p| name.starts_with(p)),
            "unprefixed name in the header (it would clash in C and C++ hosts): {name}"
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

/// The names a C header declares at file scope: macros, typedefs, structs
/// and functions (the word before the first `(` of a declaration).
fn declared_names(header: &str) -> Vec<String> {
    let word = |s: &str| {
        s.trim_start_matches('*').split(|c: char| !(c.is_alphanumeric() || c == '_')).next().unwrap_or("").to_string()
    };
    let mut names = Vec::new();
    for line in header.lines() {
        let l = line.trim();
        if let Some(rest) = l.strip_prefix("#define ") {
            names.push(word(rest));
        } else if l.starts_with("typedef") {
            let last = l.trim_end_matches(';').rsplit([' ', '*']).next().unwrap_or("");
            let name = if l.contains("(*") { word(l.split("(*").nth(1).unwrap_or("")) } else { word(last) };
            names.push(name);
        } else if let Some(rest) = l.strip_prefix("struct ") {
            names.push(word(rest));
        } else if l.starts_with('}') && l.ends_with(';') {
            names.push(word(l.trim_start_matches('}').trim()));
        } else if !l.starts_with(['#', '*', '/']) && l.contains('(') && !l.starts_with("extern") {
            names.push(word(l[..l.find('(').unwrap()].rsplit([' ', '*']).next().unwrap_or("")));
        }
    }
    names.retain(|n| !n.is_empty() && n != "HOCURVE_H");
    names
}

#[test]
fn declared_names_finds_unprefixed_ones() {
    let header = "typedef struct ElementQuality ElementQuality;\n#define HOC_OK 0\nint foo(int a);\n\
                  typedef int (*HocFn)(void *u);\ntypedef struct {\n  double x;\n} HocQ;\n";
    assert_eq!(declared_names(header), ["ElementQuality", "HOC_OK", "foo", "HocFn", "HocQ"]);
}
