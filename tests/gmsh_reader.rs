//! Tests of the Gmsh reader against the fixtures in `fixtures/meshes` (made by real Gmsh, see
//! `fixtures/meshes/README.md`), plus corrupt-input fuzzing.

use std::path::PathBuf;

use softway::io::gmsh::{parse_gmsh, read_gmsh, GmshCellKind, GmshError, GmshMesh};

const ENCODINGS: [&str; 4] = ["v22_ascii", "v22_bin", "v41_ascii", "v41_bin"];
/// Domain extents used by `make_meshes.py`.
const LX: f64 = 2.0;
const LY: f64 = 1.0;
const LZ: f64 = 0.5;

struct Case {
    name: &'static str,
    dim: usize,
    body: GmshCellKind,
    boundary: GmshCellKind,
}

const CASES: [Case; 6] = [
    Case {
        name: "square_tri3",
        dim: 2,
        body: GmshCellKind::Tri3,
        boundary: GmshCellKind::Line2,
    },
    Case {
        name: "square_tri3_reversed",
        dim: 2,
        body: GmshCellKind::Tri3,
        boundary: GmshCellKind::Line2,
    },
    Case {
        name: "square_tri3_sparse",
        dim: 2,
        body: GmshCellKind::Tri3,
        boundary: GmshCellKind::Line2,
    },
    Case {
        name: "square_quad4",
        dim: 2,
        body: GmshCellKind::Quad4,
        boundary: GmshCellKind::Line2,
    },
    Case {
        name: "box_tet4",
        dim: 3,
        body: GmshCellKind::Tet4,
        boundary: GmshCellKind::Tri3,
    },
    Case {
        name: "box_hex8",
        dim: 3,
        body: GmshCellKind::Hex8,
        boundary: GmshCellKind::Quad4,
    },
];

fn fixture(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("fixtures/meshes")
        .join(format!("{name}.msh"))
}

fn all_fixture_paths() -> Vec<PathBuf> {
    CASES
        .iter()
        .flat_map(|c| {
            ENCODINGS
                .iter()
                .map(move |e| fixture(&format!("{}_{e}", c.name)))
        })
        .collect()
}

fn load(case: &str, enc: &str) -> GmshMesh {
    let path = fixture(&format!("{case}_{enc}"));
    read_gmsh(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn norm(a: [f64; 3]) -> f64 {
    dot(a, a).sqrt()
}

/// Signed volume of the tetrahedron (a, b, c, d): positive for VTK/Gmsh orientation.
fn tet_volume(a: [f64; 3], b: [f64; 3], c: [f64; 3], d: [f64; 3]) -> f64 {
    dot(sub(b, a), cross(sub(c, a), sub(d, a))) / 6.0
}

/// Measure of an element: length, area (signed about +z for 2D meshes, unsigned on 3D
/// boundaries) or signed volume.
fn measure(mesh: &GmshMesh, kind: GmshCellKind, nodes: &[usize], signed_area: bool) -> f64 {
    let p = |i: usize| mesh.nodes[nodes[i]];
    let tri = |a: usize, b: usize, c: usize| {
        let n = cross(sub(p(b), p(a)), sub(p(c), p(a)));
        if signed_area {
            0.5 * n[2]
        } else {
            0.5 * norm(n)
        }
    };
    match kind {
        GmshCellKind::Line2 => norm(sub(p(1), p(0))),
        GmshCellKind::Tri3 => tri(0, 1, 2),
        GmshCellKind::Quad4 => tri(0, 1, 2) + tri(0, 2, 3),
        GmshCellKind::Tet4 => tet_volume(p(0), p(1), p(2), p(3)),
        // Six tetrahedra around the diagonal 0-6 (exact for the box's planar-faced hexahedra).
        GmshCellKind::Hex8 => [[1, 2], [2, 3], [3, 7], [7, 4], [4, 5], [5, 1]]
            .iter()
            .map(|&[a, b]| tet_volume(p(0), p(a), p(b), p(6)))
            .sum(),
        other => panic!("no measure for {other:?}"),
    }
}

#[test]
fn every_fixture_parses_with_physical_groups() {
    for case in &CASES {
        for enc in ENCODINGS {
            let m = load(case.name, enc);
            let what = format!("{}_{enc}", case.name);
            assert!(!m.nodes.is_empty(), "{what}");
            assert_eq!(m.highest_dimension(), Some(case.dim), "{what}");
            let dim = case.dim as i32;
            let (sd, solid) = m.physical_tag_by_name("solid").expect("solid");
            let (bd, bottom) = m.physical_tag_by_name("bottom").expect("bottom");
            assert_eq!((sd, bd), (dim, dim - 1), "{what}");
            assert!(m.physical_tag_by_name("nonexistent").is_none());
            let mut n_body = 0;
            let mut n_bottom = 0;
            for e in &m.elements {
                assert_eq!(e.nodes.len(), e.kind.node_count().expect("known kind"));
                assert!(e.nodes.iter().all(|&i| i < m.nodes.len()), "{what}");
                assert!(e.entity_tag > 0, "{what}");
                if e.kind == case.body {
                    n_body += 1;
                    assert_eq!(e.physical_tag, Some(solid), "{what}");
                } else {
                    assert_eq!(e.kind, case.boundary, "{what}");
                    assert_eq!(e.physical_tag, Some(bottom), "{what}");
                    // "bottom" is y = 0 in 2D and z = 0 in 3D.
                    let axis = case.dim - 1;
                    assert!(
                        e.nodes.iter().all(|&i| m.nodes[i][axis].abs() < 1e-12),
                        "{what}"
                    );
                    n_bottom += 1;
                }
            }
            assert!(n_body > 0 && n_bottom > 0, "{what}");
        }
    }
}

#[test]
fn encodings_give_identical_meshes() {
    for case in &CASES {
        let reference = load(case.name, "v41_ascii");
        for enc in ENCODINGS {
            let m = load(case.name, enc);
            let what = format!("{}_{enc}", case.name);
            assert_eq!(m.nodes.len(), reference.nodes.len(), "{what}");
            for (a, b) in m.nodes.iter().zip(&reference.nodes) {
                // ASCII files print 16 significant digits, so allow rounding.
                assert!(
                    (0..3).all(|k| (a[k] - b[k]).abs() < 1e-12),
                    "{what}: {a:?} vs {b:?}"
                );
            }
            assert_eq!(m.elements.len(), reference.elements.len(), "{what}");
            for (a, b) in m.elements.iter().zip(&reference.elements) {
                assert_eq!(a.kind, b.kind, "{what}");
                assert_eq!(a.nodes, b.nodes, "{what}");
                assert_eq!(a.physical_tag, b.physical_tag, "{what}");
                assert_eq!(a.entity_tag, b.entity_tag, "{what}");
            }
            assert_eq!(m.physical_names, reference.physical_names, "{what}");
        }
    }
}

#[test]
fn arbitrary_node_tags_map_to_file_order() {
    // Same mesh, nodes re-tagged (reversed contiguous; sparse): dense indices must not change.
    for variant in ["square_tri3_reversed", "square_tri3_sparse"] {
        for enc in ENCODINGS {
            let plain = load("square_tri3", enc);
            let m = load(variant, enc);
            assert_eq!(m.nodes, plain.nodes, "{variant}_{enc}");
            for (a, b) in m.elements.iter().zip(&plain.elements) {
                assert_eq!(a.nodes, b.nodes, "{variant}_{enc}");
            }
        }
    }
}

#[test]
fn element_measures_sum_to_domain_size() {
    for case in &CASES {
        for enc in ENCODINGS {
            let m = load(case.name, enc);
            let what = format!("{}_{enc}", case.name);
            let (volume, bottom) = if case.dim == 2 {
                (LX * LY, LX)
            } else {
                (LX * LY * LZ, LX * LY)
            };
            let mut sum_body = 0.0;
            let mut sum_bottom = 0.0;
            for e in &m.elements {
                if e.kind == case.body {
                    let v = measure(&m, e.kind, &e.nodes, true);
                    // Positive: Gmsh orders nodes like VTK (counter-clockwise / right-handed).
                    assert!(v > 0.0, "{what}: non-positive measure {v}");
                    sum_body += v;
                } else {
                    sum_bottom += measure(&m, e.kind, &e.nodes, false);
                }
            }
            assert!(
                (sum_body - volume).abs() < 1e-9,
                "{what}: body {sum_body} vs {volume}"
            );
            assert!(
                (sum_bottom - bottom).abs() < 1e-9,
                "{what}: bottom {sum_bottom} vs {bottom}"
            );
        }
    }
}

/// Tiny deterministic generator (no rand dependency needed).
struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> u64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        self.0 >> 33
    }
}

#[test]
fn truncated_files_are_errors() {
    for path in all_fixture_paths() {
        let bytes = std::fs::read(&path).expect("fixture");
        let n = bytes.len();
        // Every byte near both ends, and ~150 positions in between.
        let mut cuts: Vec<usize> = (0..n.min(80)).chain(n.saturating_sub(80)..n).collect();
        cuts.extend((0..n).step_by((n / 150).max(1)));
        for cut in cuts {
            let res = parse_gmsh(&bytes[..cut]);
            if bytes[cut..].iter().any(|c| !c.is_ascii_whitespace()) {
                assert!(res.is_err(), "{} cut at {cut} parsed", path.display());
            }
            if let Err(GmshError::ParserPanic { message }) = res {
                panic!("{} cut at {cut}: mshio panicked: {message}", path.display());
            }
        }
    }
}

#[test]
fn corrupted_files_do_not_panic() {
    let mut rng = Lcg(0x5eed);
    let mut errors = 0;
    let mut runs = 0;
    for path in all_fixture_paths() {
        let bytes = std::fs::read(&path).expect("fixture");
        for _ in 0..400 {
            let mut b = bytes.clone();
            // Flip 1 to 3 bytes.
            for _ in 0..1 + rng.next() % 3 {
                let i = (rng.next() as usize) % b.len();
                b[i] ^= 1 + (rng.next() % 255) as u8;
            }
            runs += 1;
            match parse_gmsh(&b) {
                Ok(_) => {}
                Err(GmshError::ParserPanic { message }) => {
                    panic!("{}: mshio panicked: {message}", path.display())
                }
                Err(e) => {
                    errors += 1;
                    // Messages must say something concrete.
                    assert!(e.to_string().len() > 10);
                }
            }
        }
    }
    eprintln!("byte-flip fuzz: {errors} of {runs} corrupted files rejected, none panicked");
}

#[test]
fn specific_corruptions_give_clear_errors() {
    assert!(matches!(
        parse_gmsh(b""),
        Err(GmshError::MissingSection { .. })
    ));
    let e = parse_gmsh(b"hello world\n").expect_err("not msh");
    assert!(e.to_string().contains("$MeshFormat"), "{e}");
    let e = parse_gmsh(b"$MeshFormat\n4.0 0 8\n$EndMeshFormat\n").expect_err("4.0");
    assert!(
        matches!(e, GmshError::UnsupportedVersion { ref found } if found == "4.0"),
        "{e}"
    );

    // A huge node count must not allocate, just report truncation.
    let e = parse_gmsh(
        b"$MeshFormat\n2.2 1 8\n\x01\x00\x00\x00\n$EndMeshFormat\n$Nodes\n999999999999999\n",
    )
    .expect_err("huge count");
    assert!(matches!(e, GmshError::Truncated { .. }), "{e}");
    let e = parse_gmsh(b"$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n99999999999\n1 0 0 0\n")
        .expect_err("huge count");
    assert!(matches!(e, GmshError::Truncated { .. }), "{e}");

    // Bad byte-order mark in a binary header.
    let e =
        parse_gmsh(b"$MeshFormat\n2.2 1 8\n\x07\x00\x00\x00\n$EndMeshFormat\n").expect_err("bom");
    assert!(matches!(e, GmshError::Binary { offset: 20, .. }), "{e}");

    // An element referring to a missing node, in each encoding.
    for enc in ENCODINGS {
        let path = fixture(&format!("square_quad4_{enc}"));
        let bytes = std::fs::read(&path).expect("fixture");
        let m = parse_gmsh(&bytes).expect("valid");
        // Drop the last node from $Nodes by renaming its tag to one nobody uses.
        let patched = retag_last_node(&bytes, enc, m.nodes.len());
        match parse_gmsh(&patched) {
            Err(GmshError::UnknownNodeTag { tag, .. }) => assert_eq!(tag, m.nodes.len(), "{enc}"),
            other => panic!("{enc}: expected UnknownNodeTag, got {other:?}"),
        }
    }

    // ASCII 4.1 errors from mshio carry the line.
    let bytes = std::fs::read(fixture("square_quad4_v41_ascii")).expect("fixture");
    let text = String::from_utf8(bytes).expect("ascii");
    let bad = text.replacen("\n0.25 0 0\n", "\n0.25 zero 0\n", 1);
    assert_ne!(bad, text);
    let line = bad.lines().position(|l| l == "0.25 zero 0").expect("line") + 1;
    match parse_gmsh(bad.as_bytes()) {
        Err(GmshError::Parse { line: l, .. }) => assert_eq!(l, line),
        other => panic!("expected Parse error, got {other:?}"),
    }
}

/// Change the tag of the node with tag `n` (the last one, as Gmsh numbers 1..n) to `n + 1000`
/// in the $Nodes section, so that elements refer to a missing tag `n`.
fn retag_last_node(bytes: &[u8], enc: &str, n: usize) -> Vec<u8> {
    let start = find(bytes, b"$Nodes\n").expect("$Nodes") + 7;
    let end = find(bytes, b"$EndNodes").expect("$EndNodes");
    let mut out = bytes.to_vec();
    let section = &mut out[start..end];
    match enc {
        "v22_ascii" | "v41_ascii" => {
            let text = String::from_utf8(section.to_vec()).expect("ascii");
            let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
            let i = lines
                .iter()
                .rposition(|l| l == &n.to_string() || l.starts_with(&format!("{n} ")))
                .expect("tag line");
            lines[i] = lines[i].replacen(&n.to_string(), &(n + 1000).to_string(), 1);
            let new = lines.join("\n") + "\n";
            let mut v = bytes[..start].to_vec();
            v.extend_from_slice(new.as_bytes());
            v.extend_from_slice(&bytes[end..]);
            return v;
        }
        "v22_bin" => {
            let pat = (n as i32).to_le_bytes();
            // Records after the count line are (int tag, 3 doubles).
            let body = find(section, b"\n").expect("count line") + 1;
            let rec = body + (n - 1) * 28;
            assert_eq!(section[rec..rec + 4], pat);
            section[rec..rec + 4].copy_from_slice(&((n + 1000) as i32).to_le_bytes());
        }
        _ => {
            let pat = (n as u64).to_le_bytes();
            // The tag appears in the header (max tag) and in its block; change the block one.
            let i = section.windows(8).rposition(|w| w == pat).expect("tag");
            assert!(i >= 32);
            section[i..i + 8].copy_from_slice(&((n + 1000) as u64).to_le_bytes());
        }
    }
    out
}

fn find(hay: &[u8], needle: &[u8]) -> Option<usize> {
    hay.windows(needle.len()).position(|w| w == needle)
}
