//! The library's modules form a chain: each uses only those before it (the
//! order `src/lib.rs` draws). Test modules may use anything.

use std::collections::BTreeSet;
use std::path::Path;

/// Bottom to top, as in the documentation of `src/lib.rs`.
const CHAIN: [&str; 20] = [
    "error",
    "jacobi",
    "linalg",
    "sparse",
    "reference",
    "quadrature",
    "mapping",
    "mesh",
    "geometry",
    "material",
    "quality",
    "assembly",
    "solver",
    "optimize",
    "curve",
    "session",
    "distributed",
    "cases",
    "io",
    "ffi",
];

/// The top-level modules that the non-test code of `text` names through `crate::`.
fn used_modules(text: &str) -> BTreeSet<String> {
    let code = match text.find("#[cfg(test)]\nmod tests") {
        Some(i) => &text[..i],
        None => text,
    };
    let mut used = BTreeSet::new();
    for line in code.lines() {
        let line = line.split("//").next().unwrap_or("");
        let mut rest = line;
        while let Some(i) = rest.find("crate::") {
            rest = &rest[i + "crate::".len()..];
            let name: String = rest.chars().take_while(|c| c.is_alphanumeric() || *c == '_').collect();
            if name.is_empty() {
                // `use crate::{a, b::c}`: every first segment in the braces.
                let group = rest.trim_start_matches('{');
                let end = group.find('}').unwrap_or(group.len());
                for part in group[..end].split(',') {
                    let first: String = part.trim().chars().take_while(|c| c.is_alphanumeric() || *c == '_').collect();
                    if !first.is_empty() {
                        used.insert(first);
                    }
                }
            } else {
                used.insert(name);
            }
        }
    }
    used
}

fn rust_files(dir: &Path, out: &mut Vec<std::path::PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

#[test]
fn every_module_uses_only_the_ones_below_it() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    let mut violations = Vec::new();
    let mut seen = BTreeSet::new();
    for f in files {
        let rel = f.strip_prefix(&src).unwrap();
        let top = rel.components().next().unwrap().as_os_str().to_string_lossy().trim_end_matches(".rs").to_string();
        // `testing` holds the unit tests' shared helpers, compiled for tests only.
        if top == "lib" || top == "bin" || top == "testing" {
            continue;
        }
        let level = CHAIN.iter().position(|&m| m == top).unwrap_or_else(|| panic!("{top} is not in the chain"));
        seen.insert(top.clone());
        for used in used_modules(&std::fs::read_to_string(&f).unwrap()) {
            // Items re-exported at the crate root (`crate::Error`) belong to `error`.
            let used =
                if ["Error", "Result", "SolverFailure"].contains(&used.as_str()) { "error".to_string() } else { used };
            if used == "testing" {
                continue; // test helpers, see above
            }
            match CHAIN.iter().position(|&m| m == used) {
                Some(u) if u > level => violations.push(format!("{} uses {used}", rel.display())),
                Some(_) => {}
                None => violations.push(format!("{} uses crate::{used}, which is not in the chain", rel.display())),
            }
        }
    }
    assert!(violations.is_empty(), "modules using ones above them:\n{}", violations.join("\n"));
    assert_eq!(seen.len(), CHAIN.len(), "modules in the chain with no file: {CHAIN:?} vs {seen:?}");
}

#[test]
fn the_scan_finds_plain_and_grouped_uses_but_not_comments_or_tests() {
    let text = "use crate::mesh::Topology;\nuse crate::{curve, solver::Foo};\n/// see [`crate::ffi`]\n\
                let x = crate::quality::f(); // crate::io\n#[cfg(test)]\nmod tests {\n    use crate::cases;\n}\n";
    let found: Vec<String> = used_modules(text).into_iter().collect();
    assert_eq!(found, ["curve", "mesh", "quality", "solver"]);
}

/// The engine's internals are crate-private unless the `internals` feature
/// asks for them: the modules the public API never needs to name.
#[test]
fn internal_modules_are_public_only_with_the_internals_feature() {
    let lib = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("src/lib.rs")).unwrap();
    let block = lib.split("internal! {").nth(1).and_then(|b| b.split('}').next()).expect("an internal! block");
    let internal: BTreeSet<&str> =
        block.lines().filter_map(|l| l.trim().strip_prefix("mod ")).map(|m| m.trim_end_matches(';')).collect();
    assert_eq!(internal, BTreeSet::from(["assembly", "jacobi", "linalg", "optimize", "sparse"]));
    for m in &internal {
        assert!(!lib.contains(&format!("pub mod {m};")), "{m} is also declared public");
    }
}

/// No function of the library outside its tests is longer than 80 lines
/// (signature to closing brace, `rustfmt` layout); generated data is exempt.
#[test]
fn no_library_function_is_longer_than_80_lines() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    let mut long = Vec::new();
    for f in files.iter().filter(|f| !f.ends_with("symmetric_data.rs")) {
        let text = std::fs::read_to_string(f).unwrap();
        let code = text.split("#[cfg(test)]\nmod tests").next().unwrap();
        let lines: Vec<&str> = code.lines().collect();
        for (i, line) in lines.iter().enumerate() {
            let trimmed = line.trim_start();
            let indent = &line[..line.len() - trimmed.len()];
            let is_fn =
                ["fn ", "pub fn ", "pub(crate) fn ", "pub(super) fn ", "unsafe fn ", "pub unsafe extern \"C\" fn "]
                    .iter()
                    .any(|p| trimmed.starts_with(p));
            // A declaration without a body (a trait's), however many lines
            // its signature takes, ends with ';' before any line opens a body.
            let declaration = lines[i..]
                .iter()
                .map(|l| l.trim_end())
                .find(|l| l.ends_with(';') || l.ends_with('{'))
                .map(|l| l.ends_with(';'));
            if !is_fn || declaration != Some(false) {
                continue;
            }
            let close = format!("{indent}}}");
            if let Some(n) = lines[i..].iter().position(|l| *l == close) {
                if n + 1 > 80 {
                    long.push(format!("{}:{} ({} lines)", f.strip_prefix(&src).unwrap().display(), i + 1, n + 1));
                }
            }
        }
    }
    assert!(long.is_empty(), "functions over 80 lines:\n{}", long.join("\n"));
}
