//! libhocurve.a and libhocurve.so carry the vendored METIS/GKlib only under
//! `hocurve_`-prefixed names (build.rs, third_party/metis/hocurve_metis_rename.h),
//! so a host linking its own METIS beside them gets no duplicate symbol and no
//! silently swapped function. Reads the libraries that `cargo test` built next
//! to this test executable with `nm` (binutils, or Xcode's on macOS).

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::process::Command;

/// Prefixes of METIS's and GKlib's own global names.
const METIS_PREFIXES: &[&str] = &["METIS_", "metis_", "libmetis__", "gk_", "GK", "HTable_"];

/// The names the rename header prefixes.
fn renamed_names() -> BTreeSet<String> {
    let header = Path::new(env!("CARGO_MANIFEST_DIR")).join("third_party/metis/hocurve_metis_rename.h");
    let text = std::fs::read_to_string(&header).unwrap();
    let names: BTreeSet<String> = text
        .lines()
        .filter_map(|l| {
            let mut w = l.strip_prefix("#define ")?.split_whitespace();
            let (name, to) = (w.next()?, w.next()?);
            (to == format!("hocurve_{name}")).then(|| name.to_string())
        })
        .collect();
    assert!(names.len() > 500 && names.contains("METIS_NodeND"), "{} names in {}", names.len(), header.display());
    names
}

/// (name, nm type letter) of every symbol; Mach-O's leading underscore removed.
fn symbols(lib: &Path, dynamic: bool) -> Vec<(String, char)> {
    let mut cmd = Command::new("nm");
    cmd.arg("-P");
    if dynamic {
        // A Mach-O dylib's global symbols are its exports.
        cmd.arg(if cfg!(target_vendor = "apple") { "-g" } else { "-D" });
    }
    let out = cmd.arg(lib).output().unwrap_or_else(|e| panic!("cannot run nm (binutils) on {}: {e}", lib.display()));
    assert!(out.status.success(), "nm {}: {}", lib.display(), String::from_utf8_lossy(&out.stderr));
    String::from_utf8_lossy(&out.stdout)
        .lines()
        .filter_map(|l| {
            let mut w = l.split_whitespace();
            let (name, kind) = (w.next()?, w.next()?.chars().next()?);
            // Archive member headers ("foo.o:") have no type letter.
            if name.ends_with(':') {
                return None;
            }
            let name = if cfg!(target_vendor = "apple") { name.strip_prefix('_').unwrap_or(name) } else { name };
            Some((name.to_string(), kind))
        })
        .collect()
}

/// The libraries built beside this test (target/<profile>/deps).
fn built_library(file: &str) -> PathBuf {
    let deps = std::env::current_exe().unwrap().parent().unwrap().to_path_buf();
    let path = deps.join(file);
    assert!(path.exists(), "{} not built", path.display());
    path
}

/// Global symbols (upper-case nm types: defined, or undefined references that
/// a host's METIS would satisfy) under an unprefixed METIS/GKlib name.
fn clashes(syms: &[(String, char)], renamed: &BTreeSet<String>) -> Vec<String> {
    syms.iter()
        .filter(|(_, kind)| kind.is_ascii_uppercase())
        .filter(|(name, _)| renamed.contains(name) || METIS_PREFIXES.iter().any(|p| name.starts_with(p)))
        .map(|(name, kind)| format!("{kind} {name}"))
        .collect::<BTreeSet<_>>()
        .into_iter()
        .collect()
}

#[test]
fn static_library_has_metis_only_under_prefixed_names() {
    let renamed = renamed_names();
    let lib = built_library("libhocurve.a");
    let syms = symbols(&lib, false);
    let bad = clashes(&syms, &renamed);
    assert!(
        bad.is_empty(),
        "{}: METIS/GKlib symbols that could clash with a host's METIS:\n{}",
        lib.display(),
        bad.join("\n")
    );
    // The rename did happen (the check above is not vacuous).
    for name in ["hocurve_METIS_NodeND", "hocurve_METIS_SetDefaultOptions", "hocurve_libmetis__MlevelNestedDissection"]
    {
        assert!(syms.iter().any(|(n, k)| n == name && *k == 'T'), "{name} not defined in {}", lib.display());
    }
}

#[test]
fn shared_library_exports_only_hoc_functions() {
    let renamed = renamed_names();
    let file = if cfg!(target_vendor = "apple") { "libhocurve.dylib" } else { "libhocurve.so" };
    let lib = built_library(file);
    let bad = clashes(&symbols(&lib, false), &renamed);
    assert!(bad.is_empty(), "{}: METIS/GKlib symbols:\n{}", lib.display(), bad.join("\n"));
    // The dynamic symbol table: the C ABI and nothing else.
    let exported: Vec<String> = symbols(&lib, true)
        .into_iter()
        .filter(|(name, kind)| *kind != 'U' && *kind != 'w' && !name.starts_with("hoc_"))
        .map(|(name, kind)| format!("{kind} {name}"))
        .collect();
    assert!(exported.is_empty(), "{} exports more than hoc_*:\n{}", lib.display(), exported.join("\n"));
}
