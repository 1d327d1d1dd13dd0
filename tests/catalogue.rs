//! The bad-input catalogue of the `.msh` reader: a table of
//! malformed files, each with the error it must give (its kind and a
//! substring of the message that says what was wrong). Every file goes
//! through the library path (`parse_msh_bytes` → `to_linear_mesh` →
//! `Session::try_new`) and, when it must fail, through the CLI (`hocurve
//! curve BAD.msh ...`: exit status 1, the message on stderr, no output file).
//! CLI-only cases (bad options, a geometry that does not match the file)
//! follow. The C ABI part of the catalogue is `c_tests/t700-catalogue.c`.
//!
//! `cargo test --release --test catalogue -- --nocapture` prints every case.

use std::path::{Path, PathBuf};
use std::process::Command;

use hocurve::io::gmsh::{parse_msh_bytes, to_linear_mesh};
use hocurve::session::Session;
use hocurve::Error;

/// What a case must give.
#[derive(Debug, Clone, Copy)]
enum Expect {
    /// `Error::Io` (a malformed file) whose message contains the text.
    Io(&'static str),
    /// `Error::InvalidInput` (a well-formed file holding a bad mesh) whose message contains the text.
    Invalid(&'static str),
    /// Accepted (the control cases, and inputs the contract says are fine).
    Ok,
}

struct Case {
    name: &'static str,
    input: Vec<u8>,
    expect: Expect,
    /// Dimension of the mesh the file was made from (picks the CLI's --geometry).
    dim: usize,
}

/// A 2D unit square with a centre vertex: 4 triangles; the bottom edge on
/// curve 1, the other three edges on curve 2. Nodes 6 and 7 (below the
/// square) are in no cell: the reader drops them, and cases use them.
const SQUARE: &str = "$MeshFormat
4.1 0 8
$EndMeshFormat
$PhysicalNames
1
2 1 \"domain\"
$EndPhysicalNames
$Nodes
1 7 1 7
2 1 0 7
1
2
3
4
5
6
7
0 0 0
1 0 0
1 1 0
0 1 0
0.5 0.5 0
0.5 -1 0
0.5 -2 0
$EndNodes
$Elements
3 8 1 8
1 1 1 1
1 1 2
1 2 1 3
2 2 3
3 3 4
4 4 1
2 1 2 4
5 1 2 5
6 2 3 5
7 3 4 5
8 4 1 5
$EndElements
";

/// The unit tetrahedron split at its centroid (node 5) into 4 tets; its four
/// faces on surface 1, its edge 1-2 on curve 1. Nodes 6 and 7 are in no cell.
const TETS: &str = "$MeshFormat
4.1 0 8
$EndMeshFormat
$Nodes
1 7 1 7
3 1 0 7
1
2
3
4
5
6
7
0 0 0
1 0 0
0 1 0
0 0 1
0.25 0.25 0.25
1 1 1
2 2 2
$EndNodes
$Elements
3 9 1 9
1 1 1 1
1 1 2
2 1 2 4
2 1 2 3
3 1 2 4
4 1 3 4
5 2 3 4
3 1 4 4
6 1 2 3 5
7 1 2 4 5
8 1 3 4 5
9 2 3 4 5
$EndElements
";

/// `base` without the text from `start` up to and including `end`.
fn remove(base: &str, start: &str, end: &str) -> Vec<u8> {
    let a = base.find(start).expect("start in base");
    let b = a + base[a..].find(end).expect("end in base") + end.len();
    [&base[..a], &base[b..]].concat().into_bytes()
}

/// `base` with `from` replaced by `to` (exactly once: a typo in the table is a test bug).
fn edit(base: &str, from: &str, to: &str) -> Vec<u8> {
    assert_eq!(base.matches(from).count(), 1, "'{from}' must occur once in the base file");
    base.replacen(from, to, 1).into_bytes()
}

/// The bytes of `base` up to (not including) the first occurrence of `marker`.
fn cut_before(base: &str, marker: &str) -> Vec<u8> {
    base.as_bytes()[..base.find(marker).expect("marker in base")].to_vec()
}

/// A binary MSH 4.1 file of two tets sharing a face (nodes 1..5) and one
/// boundary triangle, with its counts and encoding open to change.
struct Binary {
    size_t: usize,
    little: bool,
    endian_check: i32,
    nodes_header: [u64; 4],
    node_block: u64,
    elements_header: [u64; 4],
    element_block: u64,
}

impl Default for Binary {
    fn default() -> Self {
        Binary {
            size_t: 8,
            little: true,
            endian_check: 1,
            nodes_header: [1, 5, 1, 5],
            node_block: 5,
            elements_header: [2, 3, 1, 3],
            element_block: 2,
        }
    }
}

impl Binary {
    fn bytes(&self) -> Vec<u8> {
        let mut b = format!("$MeshFormat\n4.1 1 {}\n", self.size_t).into_bytes();
        let int = |b: &mut Vec<u8>, v: i32| b.extend(if self.little { v.to_le_bytes() } else { v.to_be_bytes() });
        let st = |b: &mut Vec<u8>, v: u64| {
            if self.size_t == 4 {
                let v = v as u32;
                b.extend(if self.little { v.to_le_bytes() } else { v.to_be_bytes() })
            } else {
                b.extend(if self.little { v.to_le_bytes() } else { v.to_be_bytes() })
            }
        };
        let dbl = |b: &mut Vec<u8>, v: f64| b.extend(if self.little { v.to_le_bytes() } else { v.to_be_bytes() });
        int(&mut b, self.endian_check);
        b.extend(b"\n$EndMeshFormat\n$Nodes\n");
        for v in self.nodes_header {
            st(&mut b, v);
        }
        for v in [3, 1, 0] {
            int(&mut b, v);
        }
        st(&mut b, self.node_block);
        for t in 1..=5 {
            st(&mut b, t);
        }
        for x in [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 1.0, 1.0]] {
            for c in x {
                dbl(&mut b, c);
            }
        }
        b.extend(b"\n$EndNodes\n$Elements\n");
        for v in self.elements_header {
            st(&mut b, v);
        }
        for v in [3, 1, 4] {
            int(&mut b, v);
        }
        st(&mut b, self.element_block);
        for v in [1, 1, 2, 3, 4, 2, 2, 3, 4, 5] {
            st(&mut b, v);
        }
        for v in [2, 1, 2] {
            int(&mut b, v);
        }
        st(&mut b, 1);
        for v in [3, 1, 2, 3] {
            st(&mut b, v);
        }
        b.extend(b"\n$EndElements\n");
        b
    }
}

const TWO_POW_40: &str = "1099511627776";

fn reader_cases() -> Vec<Case> {
    use Expect::*;
    let c = |name, input: Vec<u8>, expect| Case { name, input, expect, dim: 2 };
    let c3 = |name, input: Vec<u8>, expect| Case { name, input, expect, dim: 3 };
    let big = TWO_POW_40;
    let bin = Binary::default;
    vec![
        // ---- controls: the base files are fine ----
        c("control: 2D square", SQUARE.into(), Ok),
        c3("control: 3D split tetrahedron", TETS.into(), Ok),
        c3("control: binary, 8-byte size_t", bin().bytes(), Ok),
        c3("control: binary, 4-byte size_t", Binary { size_t: 4, ..bin() }.bytes(), Ok),
        c3("control: binary, big-endian", Binary { little: false, ..bin() }.bytes(), Ok),
        c("inverted cell: accepted, reoriented", edit(SQUARE, "5 1 2 5", "5 2 1 5"), Ok),
        // ---- not an MSH 4.1 file ----
        c("empty file", Vec::new(), Io("must start with $MeshFormat")),
        c("not a mesh file", b"solid cube\nfacet normal 0 0 1\n".to_vec(), Io("must start with $MeshFormat")),
        c("MSH version 2.2", edit(SQUARE, "4.1 0 8", "2.2 0 8"), Io("version 2.2 is not supported")),
        c("MSH version 4.0", edit(SQUARE, "4.1 0 8", "4.0 0 8"), Io("version 4.0 is not supported")),
        c("file type 2", edit(SQUARE, "4.1 0 8", "4.1 2 8"), Io("unsupported file type 2")),
        c("binary with data size 5", b"$MeshFormat\n4.1 1 5\n".to_vec(), Io("data size 5")),
        c3("binary endianness check not 1", Binary { endian_check: 7, ..bin() }.bytes(), Io("bad binary endianness")),
        c("raw non-UTF-8 bytes", [b"$MeshFormat\n4.1 0 8\n".as_slice(), b"\xff\xfe\n"].concat(), Io("invalid UTF-8")),
        c("non-ASCII in a number", edit(SQUARE, "0.5 0.5 0", "0.5 0.\u{b5} 0"), Io("expected a y coordinate")),
        // ---- truncated ----
        c("truncated in $MeshFormat", b"$MeshFormat\n4.1 0".to_vec(), Io("unexpected end of file")),
        c("truncated in the coordinates", cut_before(SQUARE, "0.5 0.5 0"), Io("unexpected end of file")),
        c("truncated in $Elements", cut_before(SQUARE, "7 3 4 5"), Io("unexpected end of file")),
        c("missing $EndElements", cut_before(SQUARE, "$EndElements"), Io("expected $EndElements")),
        c("missing $Elements section", cut_before(SQUARE, "$Elements"), Io("missing $Elements section")),
        c("missing $Nodes section", remove(SQUARE, "$Nodes", "$EndNodes\n"), Io("missing $Nodes section")),
        c("skipped section never ends", edit(SQUARE, "$EndPhysicalNames", ""), Io("missing $EndPhysicalNames")),
        c3("binary, truncated in the coordinates", bin().bytes()[..150].to_vec(), Io("unexpected end of file")),
        // ---- wrong counts ----
        c("$Nodes announces 8 nodes, holds 7", edit(SQUARE, "1 7 1 7", "1 8 1 7"), Io("announces 8 nodes")),
        c(
            "node block announces 8 nodes, holds 7",
            edit(SQUARE, "2 1 0 7", "2 1 0 8"),
            Io("announces more nodes than it holds"),
        ),
        c("node block announces 6 nodes, holds 7", edit(SQUARE, "2 1 0 7", "2 1 0 6"), Io("the blocks hold 6")),
        c("$Elements announces 9, holds 8", edit(SQUARE, "3 8 1 8", "3 9 1 8"), Io("announces 9 elements")),
        c(
            "element block announces 5, holds 4",
            edit(SQUARE, "2 1 2 4", "2 1 2 5"),
            Io("found '$EndElements' (the section ends early: wrong counts?)"),
        ),
        c("2 element blocks announced, 3 present", edit(SQUARE, "3 8 1 8", "2 8 1 8"), Io("announces 8 elements")),
        c("negative count", edit(SQUARE, "1 7 1 7", "1 -7 1 7"), Io("unsigned integer")),
        c("count overflows 64 bits", edit(SQUARE, "1 7 1 7", "1 18446744073709551616 1 7"), Io("unsigned integer")),
        // ---- enormous claims: fail without allocating for them ----
        c(
            "$Nodes claims 2^40 nodes",
            edit(SQUARE, "1 7 1 7", &format!("1 {big} 1 {big}")),
            Io("announces 1099511627776 nodes"),
        ),
        c(
            "node block claims 2^40 nodes",
            edit(SQUARE, "2 1 0 7", &format!("2 1 0 {big}")),
            Io("announces more nodes than it holds"),
        ),
        c("$Nodes claims 2^40 blocks", edit(SQUARE, "1 7 1 7", &format!("{big} 7 1 7")), Io("wrong counts?")),
        c("element block claims 2^40 cells", edit(SQUARE, "2 1 2 4", &format!("2 1 2 {big}")), Io("wrong counts?")),
        c3(
            "binary $Nodes claims 2^40 nodes",
            Binary { nodes_header: [1, 1 << 40, 1, 1 << 40], ..bin() }.bytes(),
            Io("announces 1099511627776 nodes"),
        ),
        c3("binary node block claims 2^40 nodes", Binary { node_block: 1 << 40, ..bin() }.bytes(), Io("node tag 0")),
        c3("binary element block claims 2^62", Binary { element_block: 1 << 62, ..bin() }.bytes(), Io("end of file")),
        c3(
            "binary (4-byte size_t) claims 2^32-1 nodes",
            Binary { size_t: 4, nodes_header: [1, u32::MAX as u64, 1, 5], ..bin() }.bytes(),
            Io("announces 4294967295 nodes"),
        ),
        // ---- bad numbers and tags ----
        c("NaN coordinate", edit(SQUARE, "0.5 0.5 0", "0.5 nan 0"), Io("non-finite a y coordinate")),
        c("infinite coordinate", edit(SQUARE, "0.5 0.5 0", "inf 0.5 0"), Io("non-finite an x coordinate")),
        c("coordinate 1e400 overflows", edit(SQUARE, "0.5 0.5 0", "0.5 1e400 0"), Io("non-finite")),
        c("huge coordinates (1e300)", edit(SQUARE, "1 1 0\n", "1e300 1e300 0\n"), Invalid("too large")),
        c(
            "huge coordinates, measure inf - inf = NaN",
            edit(SQUARE, "1 0 0\n1 1 0\n", "1e300 1e300 0\n1e300 2e300 0\n"),
            Invalid("too large"),
        ),
        c("text for a coordinate", edit(SQUARE, "0.5 0.5 0", "0.5 half 0"), Io("found 'half'")),
        c("node tag 0", edit(SQUARE, "2 1 0 7\n1\n", "2 1 0 7\n0\n"), Io("node tag 0")),
        c("node tag given twice", edit(SQUARE, "3\n4\n5\n", "3\n3\n5\n"), Io("node tag 3 appears twice")),
        c("element uses an unknown node tag", edit(SQUARE, "8 4 1 5", "8 4 1 55"), Io("unknown node tag 55")),
        c("bad node block header", edit(SQUARE, "2 1 0 7", "2 1 2 7"), Io("bad node block header")),
        // ---- wrong element types and entity dimensions ----
        c("unknown element type 999", edit(SQUARE, "2 1 2 4", "2 1 999 4"), Io("unsupported element type 999")),
        c("triangles on a curve entity", edit(SQUARE, "2 1 2 4", "1 1 2 4"), Io("on an entity of dim 1")),
        c("negative entity dimension", edit(SQUARE, "2 1 2 4", "-1 1 2 4"), Io("on an entity of dim -1")),
        c(
            "no triangles or tetrahedra",
            remove(&SQUARE.replace("3 8 1 8", "2 4 1 4"), "2 1 2 4", "8 4 1 5\n"),
            Io("no linear triangles (type 2) or tetrahedra (type 4)"),
        ),
        c(
            "quadratic triangle (type 9)",
            edit(
                &SQUARE.replace("3 8 1 8", "3 5 1 8"),
                "2 1 2 4\n5 1 2 5\n6 2 3 5\n7 3 4 5\n8 4 1 5\n",
                "2 1 9 1\n5 1 2 3 6 7 5\n",
            ),
            Io("must be linear simplices only"),
        ),
        c(
            "a quad among the triangles",
            edit(SQUARE, "3 8 1 8\n", "4 9 1 9\n2 2 3 1\n9 1 2 3 4\n"),
            Io("element type 3"),
        ),
        c(
            "zero elements",
            remove(&SQUARE.replace("3 8 1 8", "0 0 0 0"), "1 1 1 1", "8 4 1 5\n"),
            Io("no linear triangles"),
        ),
        c("zero nodes", remove(&SQUARE.replace("1 7 1 7", "0 0 0 0"), "2 1 0 7", "0.5 -2 0\n"), Io("unknown node tag")),
        // ---- bad meshes in well-formed files ----
        c("duplicate cell", edit(SQUARE, "8 4 1 5", "8 5 2 1"), Invalid("have the same vertices")),
        c("cell repeats a vertex", edit(SQUARE, "8 4 1 5", "8 4 1 4"), Invalid("repeats a vertex")),
        c("degenerate (zero-area) cell", edit(SQUARE, "0.5 0.5 0", "0.5 0 0"), Invalid("degenerate")),
        c(
            "non-manifold: three triangles on an edge",
            edit(SQUARE, "3 8 1 8\n", "4 10 1 10\n2 2 2 2\n9 1 2 6\n10 1 2 7\n"),
            Invalid("not manifold"),
        ),
        c3(
            "non-manifold: three tets on a face",
            edit(TETS, "3 9 1 9\n", "4 11 1 11\n3 2 4 2\n10 2 3 4 6\n11 2 3 4 7\n"),
            Invalid("not manifold"),
        ),
        c(
            "facet tagged twice",
            edit(SQUARE, "3 8 1 8\n1 1 1 1\n1 1 2\n", "4 9 1 9\n1 1 1 1\n1 1 2\n1 1 1 1\n9 2 1\n"),
            Invalid("tagged twice"),
        ),
        c("interior edge tagged as boundary", edit(SQUARE, "1 1 2\n", "1 1 5\n"), Invalid("not a boundary facet")),
        c(
            "boundary edge on a node in no cell",
            edit(SQUARE, "1 1 2\n", "1 1 6\n"),
            Io("uses node 6 which is in no cell"),
        ),
        c3("interior face tagged as boundary", edit(TETS, "2 1 2 3\n", "2 1 2 5\n"), Invalid("not a boundary facet")),
        c3("feature edge inside the solid", edit(TETS, "1 1 2\n", "1 1 5\n"), Invalid("not an edge of the boundary")),
        c3(
            "feature edge tagged twice",
            edit(TETS, "3 9 1 9\n1 1 1 1\n1 1 2\n", "4 10 1 10\n1 1 1 1\n1 1 2\n1 1 1 1\n10 2 1\n"),
            Invalid("tagged twice"),
        ),
        // ---- structure ----
        c("stray token between sections", edit(SQUARE, "$Nodes\n", "garbage\n$Nodes\n"), Io("found 'garbage'")),
        c("misspelt $EndNodes", edit(SQUARE, "$EndNodes", "$EndNode"), Io("expected $EndNodes, found '$EndNode'")),
        c("$End marker with no section", edit(SQUARE, "$Nodes\n", "$EndFoo\n$Nodes\n"), Io("found '$EndFoo'")),
    ]
}

/// The library path: read, convert, create a session (validation, topology,
/// boundary classification).
fn load(input: &[u8]) -> hocurve::Result<Session> {
    let msh = parse_msh_bytes(input)?;
    let mesh = to_linear_mesh(&msh)?;
    Session::try_new(mesh)
}

fn check(expect: Expect, got: &hocurve::Result<Session>) -> Result<String, String> {
    match (expect, got) {
        (Expect::Ok, Ok(s)) => Ok(format!("accepted ({} cells)", s.mesh().n_cells())),
        (Expect::Io(needle), Err(Error::Io(m))) | (Expect::Invalid(needle), Err(Error::InvalidInput(m)))
            if m.contains(needle) =>
        {
            Ok(m.clone())
        }
        (want, Ok(_)) => Err(format!("accepted, expected {want:?}")),
        (want, Err(e)) => Err(format!("got {e:?}, expected {want:?}")),
    }
}

fn scratch_dir() -> PathBuf {
    let dir = std::env::temp_dir().join(format!("hocurve-catalogue-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// `hocurve curve IN --order 2 ARGS... --output OUT.msh`: (exit code, stderr, output written?).
fn cli(input: &Path, args: &[&str], out: &Path) -> (Option<i32>, String, bool) {
    let _ = std::fs::remove_file(out);
    let o = Command::new(env!("CARGO_BIN_EXE_hocurve"))
        .arg("curve")
        .arg(input)
        .args(args)
        .arg("--output")
        .arg(out)
        .output()
        .expect("run hocurve");
    (o.status.code(), String::from_utf8_lossy(&o.stderr).into_owned(), out.exists())
}

/// `--order 2` and shapes for the tags of the base files.
fn geometry_for(dim: usize) -> Vec<&'static str> {
    if dim == 3 {
        vec!["--order", "2", "--geometry", "1=plane:0,0,0,0,0,1", "--geometry", "1=line:0,0,0,1,0,0"]
    } else {
        vec!["--order", "2", "--geometry", "1=line:0,0,0,1,0,0"]
    }
}

#[test]
fn msh_reader_catalogue() {
    let dir = scratch_dir();
    let cases = reader_cases();
    let (mut failures, mut rejected, mut cli_checked) = (Vec::new(), 0, 0);
    for (k, case) in cases.iter().enumerate() {
        let got = load(&case.input);
        match check(case.expect, &got) {
            Ok(m) => println!("ok   {:<48} {m}", case.name),
            Err(m) => {
                println!("FAIL {:<48} {m}", case.name);
                failures.push(format!("{}: {m}", case.name));
            }
        }
        let needle = match case.expect {
            Expect::Ok => continue,
            Expect::Io(n) | Expect::Invalid(n) => n,
        };
        rejected += 1;
        // The same file through the CLI: exit status 1, the message on stderr, no output.
        let input = dir.join(format!("case{k}.msh"));
        std::fs::write(&input, &case.input).unwrap();
        let out = dir.join(format!("case{k}-out.msh"));
        let (code, stderr, wrote) = cli(&input, &geometry_for(case.dim), &out);
        if code != Some(1) || !stderr.contains(needle) || wrote {
            failures.push(format!("{} (CLI): exit {code:?}, wrote output: {wrote}, stderr {stderr:?}", case.name));
        } else {
            cli_checked += 1;
        }
    }
    // Every truncation of the valid files is an error, never a panic (counted as one case each).
    for base in [SQUARE.as_bytes().to_vec(), Binary::default().bytes()] {
        for cut in 0..base.len() - 1 {
            if load(&base[..cut]).is_ok() {
                failures.push(format!("truncation at byte {cut} accepted"));
            }
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
    println!(
        "msh catalogue: {} cases ({} malformed, each rejected by the reader and by `hocurve curve` [{} checked]), \
         plus every truncation of two files; {} failures",
        cases.len(),
        rejected,
        cli_checked,
        failures.len()
    );
    assert!(failures.is_empty(), "catalogue failures:\n{}", failures.join("\n"));
}

/// Bad command lines of `hocurve curve` and `hocurve quality` on good files:
/// (name, arguments with IN standing for the input file, stderr substring).
/// `IN2` is the 2D square, `IN3` the 3D split tetrahedron.
const CLI_CASES: &[(&str, &[&str], &str)] = &[
    ("input file missing", &["curve", "nonexistent.msh", "--order", "2"], "nonexistent.msh: No such file"),
    ("input is a directory", &["curve", "DIR", "--order", "2"], "Is a directory"),
    ("no input file", &["curve", "--order", "2"], "curve needs an input .msh file"),
    ("two input files", &["curve", "IN2", "IN2", "--order", "2"], "curve takes one input file, got 2"),
    ("no --order", &["curve", "IN2"], "curve needs --order P"),
    ("--order 0", &["curve", "IN2", "--order", "0"], "order must be between 1 and 10, got 0"),
    ("--order 11", &["curve", "IN2", "--order", "11"], "order must be between 1 and 10, got 11"),
    ("--order -1", &["curve", "IN2", "--order", "-1"], "--order: '-1' is not a valid number"),
    ("--order two", &["curve", "IN2", "--order", "two"], "--order: 'two' is not a valid number"),
    ("--poisson 0.5", &["curve", "IN2", "--order", "2", "--poisson", "0.5"], "Poisson"),
    ("--poisson nan", &["curve", "IN2", "--order", "2", "--poisson", "nan"], "Poisson"),
    ("--young -1", &["curve", "IN2", "--order", "2", "--young", "-1"], "Young"),
    ("--young inf", &["curve", "IN2", "--order", "2", "--young", "inf"], "Young"),
    ("--increments 0", &["curve", "IN2", "--order", "2", "--increments", "0"], "increments must be at least 1"),
    ("unknown formulation", &["curve", "IN2", "--order", "2", "--formulation", "magic"], "magic"),
    ("unknown material", &["curve", "IN2", "--order", "2", "--material", "rubber"], "rubber"),
    (
        "CIL with a linear material",
        &["curve", "IN2", "--order", "2", "--formulation", "cil", "--material", "linear"],
        "needs a hyperelastic material",
    ),
    ("unknown spacing", &["curve", "IN2", "--order", "2", "--spacing", "chebyshev"], "unknown spacing 'chebyshev'"),
    ("unknown --caps", &["curve", "IN2", "--order", "2", "--caps", "maybe"], "unknown --caps 'maybe'"),
    ("unknown --repair", &["curve", "IN2", "--order", "2", "--repair", "maybe"], "unknown --repair 'maybe'"),
    ("unknown solver", &["curve", "IN2", "--order", "2", "--solver", "magic"], "magic"),
    (
        "unknown --tangent-first",
        &["curve", "IN2", "--order", "2", "--tangent-first", "maybe"],
        "unknown --tangent-first 'maybe'",
    ),
    ("unknown option", &["curve", "IN2", "--order", "2", "--frobnicate", "1"], "unknown option --frobnicate"),
    ("option without a value", &["curve", "IN2", "--output", "OUT", "--order"], "option --order needs a value"),
    ("--geometry without '='", &["curve", "IN2", "--order", "2", "--geometry", "line"], "expected TAG=SHAPE"),
    (
        "--geometry tag not a number",
        &["curve", "IN2", "--order", "2", "--geometry", "x=line:0,0,0,1,0,0"],
        "not an integer tag",
    ),
    ("unknown shape", &["curve", "IN2", "--order", "2", "--geometry", "1=blob:1,2"], "blob"),
    ("shape with too few numbers", &["curve", "IN2", "--order", "2", "--geometry", "1=circle:0,0"], "circle"),
    ("shape with NaN", &["curve", "IN2", "--order", "2", "--geometry", "1=circle:0,0,nan"], "circle"),
    ("tag not in the file", &["curve", "IN2", "--order", "2", "--geometry", "9=line:0,0,0,1,0,0"], "no boundary facet"),
    (
        "surface tag given a curve shape in 3D",
        &["curve", "IN3", "--order", "2", "--geometry", "7=circle3:0,0,0,0,0,1,1"],
        "no boundary feature curve",
    ),
    (
        "projector moves points off the entity (geometry 5 away)",
        &["curve", "IN2", "--order", "2", "--geometry", "1=line:0,5,0,1,0,0"],
        "more than the size of its elements",
    ),
    (
        "projector moves points off the entity (sphere far away)",
        &["curve", "IN3", "--order", "2", "--geometry", "1=sphere:10,10,10,1"],
        "more than the size of its elements",
    ),
    ("output extension", &["curve", "IN2", "--order", "2", "--output", "OUT.txt"], "must end in .msh or .vtu"),
    ("output directory missing", &["curve", "IN2", "--order", "2", "--output", "/nonexistent/o.msh"], "does not exist"),
    ("quality: truncated file", &["quality", "CUT"], "unexpected end of file"),
    ("quality: no file", &["quality"], "quality needs exactly one .msh file"),
    ("unknown command", &["bend", "IN2"], "unknown command 'bend'"),
];

#[test]
fn cli_catalogue() {
    let dir = scratch_dir().join("cli");
    std::fs::create_dir_all(&dir).unwrap();
    let in2 = dir.join("square.msh");
    let in3 = dir.join("tets.msh");
    let cut = dir.join("cut.msh");
    std::fs::write(&in2, SQUARE).unwrap();
    std::fs::write(&in3, TETS).unwrap();
    std::fs::write(&cut, &SQUARE.as_bytes()[..SQUARE.len() / 2]).unwrap();
    let out = dir.join("out.msh");
    let run = |args: &[&str]| {
        let args: Vec<String> = args
            .iter()
            .map(|a| match *a {
                "IN2" => in2.display().to_string(),
                "IN3" => in3.display().to_string(),
                "CUT" => cut.display().to_string(),
                "DIR" => dir.display().to_string(),
                "OUT.txt" => dir.join("out.txt").display().to_string(),
                "OUT" => out.display().to_string(),
                a => a.to_string(),
            })
            .collect();
        let mut cmd = Command::new(env!("CARGO_BIN_EXE_hocurve"));
        cmd.args(&args).current_dir(&dir);
        if args[0] == "curve" && !args.iter().any(|a| a == "--output") {
            cmd.arg("--output").arg(&out);
        }
        let _ = std::fs::remove_file(&out);
        let o = cmd.output().expect("run hocurve");
        (o.status.code(), String::from_utf8_lossy(&o.stderr).into_owned(), out.exists())
    };
    // Controls: the base files curve.
    let (code, stderr, wrote) = run(&["curve", "IN2", "--order", "2", "--geometry", "1=line:0,0,0,1,0,0"]);
    assert!(code == Some(0) && wrote, "control 2D failed: {stderr}");
    let (code, stderr, wrote) = run(&["curve", "IN3", "--order", "2", "--geometry", "1=line:0,0,0,1,0,0"]);
    assert!(code == Some(0) && wrote, "control 3D failed: {stderr}");
    let mut failures = Vec::new();
    for (name, args, needle) in CLI_CASES {
        let (code, stderr, wrote) = run(args);
        let msg = stderr.lines().find(|l| l.starts_with("hocurve: error:")).unwrap_or("").to_string();
        if code == Some(1) && msg.contains(needle) && !wrote {
            println!("ok   {name:<56} {msg}");
        } else {
            println!("FAIL {name:<56} exit {code:?}, output written: {wrote}, stderr {stderr:?}");
            failures.push(*name);
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
    println!("CLI catalogue: {} cases, {} failures", CLI_CASES.len(), failures.len());
    assert!(failures.is_empty(), "CLI catalogue failures: {failures:?}");
}
