//! Tests of the VTK writers: read back with an XML parser (`quick-xml`) and a base64 decoder
//! here, and, when Python has them, with meshio (values round-trip) and pyvista/VTK (cell
//! volumes, i.e. node ordering; .pvd).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

use quick_xml::events::{BytesStart, Event};
use quick_xml::XmlVersion;
use softway::io::gmsh::{read_gmsh, GmshCellKind};
use softway::io::vtk::{write_pvd, write_vtu, VtkCellKind, VtkField, VtkPiece};

/// A small mixed mesh: a unit cube hexahedron (points 0-7), a tetrahedron on top of it (8),
/// a quad and a triangle beside it, and a line.
struct Mixed {
    points: Vec<[f64; 3]>,
    cells: Vec<(VtkCellKind, Vec<usize>)>,
    u: Vec<f64>,
    p: Vec<f64>,
    id: Vec<f64>,
    stress: Vec<f64>,
}

fn mixed() -> Mixed {
    let mut points = vec![
        [0., 0., 0.],
        [1., 0., 0.],
        [1., 1., 0.],
        [0., 1., 0.],
        [0., 0., 1.],
        [1., 0., 1.],
        [1., 1., 1.],
        [0., 1., 1.],
        [0.5, 0.5, 2.],
        [2., 0., 0.],
        [2., 1., 0.],
        [3., 0., 0.],
    ];
    // Awkward values so that any rounding would show.
    points[8][0] += 1.0 / 3.0;
    let cells = vec![
        (VtkCellKind::Hex8, vec![0, 1, 2, 3, 4, 5, 6, 7]),
        (VtkCellKind::Tet4, vec![4, 5, 6, 8]),
        (VtkCellKind::Quad4, vec![1, 9, 10, 2]),
        (VtkCellKind::Tri3, vec![9, 11, 10]),
        (VtkCellKind::Line2, vec![9, 11]),
    ];
    let n = points.len();
    let u = (0..3 * n).map(|i| (i as f64).sin() * 1e-3).collect();
    let p = (0..n).map(|i| 1.0 / (i as f64 + 7.0)).collect();
    let id = (0..cells.len()).map(|i| i as f64 + 0.5).collect();
    let stress = (0..9 * cells.len())
        .map(|i| (i as f64).sqrt() - 1e10)
        .collect();
    Mixed {
        points,
        cells,
        u,
        p,
        id,
        stress,
    }
}

/// Write the mixed mesh to `path`.
fn write_mixed(path: &Path, m: &Mixed) {
    let cells: Vec<(VtkCellKind, &[usize])> =
        m.cells.iter().map(|(k, c)| (*k, c.as_slice())).collect();
    let point_data = [
        VtkField {
            name: "displacement",
            components: 3,
            values: &m.u,
        },
        VtkField {
            name: "pressure <p> & \"q\"",
            components: 1,
            values: &m.p,
        },
    ];
    let cell_data = [
        VtkField {
            name: "id",
            components: 1,
            values: &m.id,
        },
        VtkField {
            name: "stress",
            components: 9,
            values: &m.stress,
        },
    ];
    let piece = VtkPiece {
        points: &m.points,
        cells: &cells,
        point_data: &point_data,
        cell_data: &cell_data,
    };
    write_vtu(path, &piece).expect("write_vtu");
}

/// The attributes of an element, unescaped.
fn attributes(e: &BytesStart) -> BTreeMap<String, String> {
    e.attributes()
        .map(|a| {
            let a = a.expect("well-formed attribute");
            let key = a.key.as_ref().to_string();
            let value = a.normalized_value(XmlVersion::Explicit1_0).expect("value");
            (key, value.into_owned())
        })
        .collect()
}

/// Standard base64 with padding (what VTK's inline "binary" format uses).
fn base64_decode(text: &str) -> Vec<u8> {
    let value = |c: u8| -> u32 {
        match c {
            b'A'..=b'Z' => u32::from(c - b'A'),
            b'a'..=b'z' => u32::from(c - b'a') + 26,
            b'0'..=b'9' => u32::from(c - b'0') + 52,
            b'+' => 62,
            b'/' => 63,
            other => panic!("not base64: {:?}", other as char),
        }
    };
    let text = text.trim().as_bytes();
    assert_eq!(text.len() % 4, 0, "base64 comes in groups of 4");
    let mut out = Vec::new();
    for group in text.chunks(4) {
        let pad = group.iter().filter(|&&c| c == b'=').count();
        let n = group[..4 - pad]
            .iter()
            .enumerate()
            .fold(0u32, |n, (k, &c)| n | (value(c) << (18 - 6 * k)));
        out.extend_from_slice(&n.to_be_bytes()[1..4 - pad]);
    }
    out
}

/// A `<DataArray>` read back: where it is, its attributes and its decoded bytes (the UInt64
/// byte-count header checked and removed).
#[derive(Debug)]
struct Array {
    /// The enclosing element: PointData, CellData, Points or Cells.
    section: String,
    attributes: BTreeMap<String, String>,
    bytes: Vec<u8>,
}

impl Array {
    fn f64s(&self) -> Vec<f64> {
        assert_eq!(self.attributes["type"], "Float64");
        let (chunks, _) = self.bytes.as_chunks::<8>();
        chunks.iter().map(|&c| f64::from_le_bytes(c)).collect()
    }

    fn u64s(&self) -> Vec<u64> {
        assert_eq!(self.attributes["type"], "UInt64");
        let (chunks, _) = self.bytes.as_chunks::<8>();
        chunks.iter().map(|&c| u64::from_le_bytes(c)).collect()
    }

    fn components(&self) -> usize {
        self.attributes
            .get("NumberOfComponents")
            .map_or(1, |n| n.parse().expect("integer"))
    }
}

/// Parses a `.vtu` as XML: the root's and the piece's attributes, and every data array.
fn read_vtu(
    text: &str,
) -> (
    BTreeMap<String, String>,
    BTreeMap<String, String>,
    Vec<Array>,
) {
    let mut reader = quick_xml::Reader::from_str(text);
    let (mut root, mut piece, mut arrays) = (BTreeMap::new(), BTreeMap::new(), Vec::new());
    let mut stack: Vec<String> = Vec::new();
    let mut current: Option<Array> = None;
    loop {
        match reader.read_event().expect("well-formed XML") {
            Event::Start(e) | Event::Empty(e) if e.name().as_ref() == "DataArray" => {
                assert!(current.is_none(), "nested DataArray");
                current = Some(Array {
                    section: stack.last().cloned().expect("inside a section"),
                    attributes: attributes(&e),
                    bytes: Vec::new(),
                });
                stack.push("DataArray".into());
            }
            Event::Start(e) => {
                let name = e.name().as_ref().to_string();
                match name.as_str() {
                    "VTKFile" => root = attributes(&e),
                    "Piece" => piece = attributes(&e),
                    _ => {}
                }
                stack.push(name);
            }
            Event::Text(t) => {
                if let Some(a) = current.as_mut() {
                    let bytes = base64_decode(&t.xml10_content());
                    let (header, data) = bytes.split_at(8);
                    let count = u64::from_le_bytes(header.try_into().unwrap());
                    assert_eq!(count as usize, data.len(), "UInt64 byte-count header");
                    a.bytes = data.to_vec();
                }
            }
            Event::End(e) => {
                let name = stack.pop().expect("balanced tags");
                assert_eq!(e.name().as_ref(), name);
                if name == "DataArray" {
                    arrays.push(current.take().expect("open DataArray"));
                }
            }
            Event::Eof => break,
            _ => {}
        }
    }
    assert!(stack.is_empty(), "unclosed {stack:?}");
    (root, piece, arrays)
}

fn array<'a>(arrays: &'a [Array], section: &str, name: Option<&str>) -> &'a Array {
    arrays
        .iter()
        .find(|a| a.section == section && a.attributes.get("Name").map(String::as_str) == name)
        .unwrap_or_else(|| panic!("no array {name:?} in {section}"))
}

#[test]
fn vtu_reads_back_as_xml() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("mixed.vtu");
    let m = mixed();
    write_mixed(&path, &m);
    assert!(
        !dir.path().join("mixed.vtu.tmp").exists(),
        "temporary left behind"
    );
    let text = std::fs::read_to_string(&path).expect("read");
    assert!(
        text.starts_with("<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\""),
        "{}",
        &text[..80]
    );

    let (root, piece, arrays) = read_vtu(&text);
    assert_eq!(root["type"], "UnstructuredGrid");
    assert_eq!(root["version"], "1.0");
    assert_eq!(root["byte_order"], "LittleEndian");
    assert_eq!(root["header_type"], "UInt64");
    assert_eq!(piece["NumberOfPoints"], m.points.len().to_string());
    assert_eq!(piece["NumberOfCells"], m.cells.len().to_string());
    assert_eq!(arrays.len(), 8, "{arrays:?}");

    let points = array(&arrays, "Points", None);
    assert_eq!(points.components(), 3);
    let expected: Vec<f64> = m.points.iter().flatten().copied().collect();
    assert_eq!(points.f64s(), expected);
    let conn: Vec<u64> = m
        .cells
        .iter()
        .flat_map(|(_, c)| c.iter().map(|&i| i as u64))
        .collect();
    assert_eq!(array(&arrays, "Cells", Some("connectivity")).u64s(), conn);
    assert_eq!(
        array(&arrays, "Cells", Some("offsets")).u64s(),
        vec![8, 12, 16, 19, 21]
    );
    let types = array(&arrays, "Cells", Some("types"));
    assert_eq!(types.attributes["type"], "UInt8");
    assert_eq!(types.bytes, vec![12, 10, 9, 5, 3]);
    for (section, name, components, values) in [
        ("PointData", "displacement", 3, &m.u),
        ("PointData", "pressure <p> & \"q\"", 1, &m.p),
        ("CellData", "id", 1, &m.id),
        ("CellData", "stress", 9, &m.stress),
    ] {
        let a = array(&arrays, section, Some(name));
        assert_eq!((a.components(), &a.f64s()), (components, values), "{name}");
    }
}

#[test]
fn vtu_without_fields_or_cells() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("empty.vtu");
    let piece = VtkPiece {
        points: &[[0.5, -1.0, 2.0]],
        cells: &[],
        point_data: &[],
        cell_data: &[],
    };
    write_vtu(&path, &piece).expect("write");
    let text = std::fs::read_to_string(&path).expect("read");
    let (_, piece, arrays) = read_vtu(&text);
    assert_eq!(piece["NumberOfPoints"], "1");
    assert_eq!(piece["NumberOfCells"], "0");
    assert_eq!(array(&arrays, "Points", None).f64s(), vec![0.5, -1.0, 2.0]);
    assert!(array(&arrays, "Cells", Some("offsets")).bytes.is_empty());
}

#[test]
fn pvd_structure() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("run.pvd");
    let entries = vec![
        (0.0, "frames/step_0000.vtu".to_string()),
        (0.1, "frames/step_0001.vtu".to_string()),
        (1e-300, "odd & <name>.vtu".to_string()),
    ];
    write_pvd(&path, &entries).expect("write_pvd");
    let text = std::fs::read_to_string(&path).expect("read");
    assert!(text.starts_with("<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\""));
    assert_eq!(text.matches("<DataSet ").count(), 3);
    assert!(text.contains("timestep=\"0.1\" group=\"\" part=\"0\" file=\"frames/step_0001.vtu\""));
    assert!(text.contains("timestep=\"1e-300\""));
    assert!(text.contains("file=\"odd &amp; &lt;name&gt;.vtu\""));
    assert!(text.trim_end().ends_with("</VTKFile>"));
    let mut reader = quick_xml::Reader::from_str(&text);
    let mut files = Vec::new();
    loop {
        match reader.read_event().expect("well-formed XML") {
            Event::Empty(e) if e.name().as_ref() == "DataSet" => {
                let a = attributes(&e);
                files.push((
                    a["timestep"].parse::<f64>().expect("time"),
                    a["file"].clone(),
                ));
            }
            Event::Eof => break,
            _ => {}
        }
    }
    assert_eq!(files, entries);
    let bad = write_pvd(&path, &[(f64::NAN, "x.vtu".into())]).expect_err("NaN time");
    assert_eq!(bad.kind(), std::io::ErrorKind::InvalidInput);
}

#[test]
fn invalid_piece_writes_nothing() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("bad.vtu");
    let points = [[0.0; 3]; 2];
    let cells: [(VtkCellKind, &[usize]); 1] = [(VtkCellKind::Line2, &[0, 2])];
    let piece = VtkPiece {
        points: &points,
        cells: &cells,
        point_data: &[],
        cell_data: &[],
    };
    let err = write_vtu(&path, &piece).expect_err("index out of range");
    assert_eq!(err.kind(), std::io::ErrorKind::InvalidInput);
    assert!(err.to_string().contains("point 2"), "{err}");
    assert!(!path.exists() && !dir.path().join("bad.vtu.tmp").exists());
}

// ---------------------------------------------------------------------------------------------
// Python cross-checks (skipped with a notice when python3 or the module is missing)
// ---------------------------------------------------------------------------------------------

fn python() -> String {
    std::env::var("PYTHON").unwrap_or_else(|_| "python3".to_string())
}

/// Run a Python script with arguments; `None` (after printing why) if `module` is unavailable.
fn run_python(module: &str, script: &str, args: &[&Path]) -> Option<String> {
    let probe = Command::new(python())
        .args(["-c", &format!("import {module}")])
        .output();
    match probe {
        Ok(o) if o.status.success() => {}
        _ => {
            eprintln!(
                "NOTICE: skipping: `{} -c 'import {module}'` failed (pip install {module})",
                python()
            );
            return None;
        }
    }
    let out = Command::new(python())
        .arg("-c")
        .arg(script)
        .args(args)
        .output()
        .expect("run python");
    assert!(
        out.status.success(),
        "python failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    Some(String::from_utf8(out.stdout).expect("utf8"))
}

/// Dump what meshio reads: one line per array, `kind name v1 v2 ...` with exact float reprs.
const MESHIO_DUMP: &str = r#"
import sys, meshio
m = meshio.read(sys.argv[1])
def line(*xs): print(" ".join(str(x) for x in xs))
line("points", *[repr(float(v)) for v in m.points.ravel()])
for b in m.cells:
    line("cells", b.type, *[int(v) for v in b.data.ravel()])
for name, a in m.point_data.items():
    line("point", name.replace(" ", "_"), a.reshape(len(m.points), -1).shape[1], *[repr(float(v)) for v in a.ravel()])
for name, blocks in m.cell_data.items():
    vals = [repr(float(v)) for b in blocks for v in b.ravel()]
    line("cell", name.replace(" ", "_"), len(vals) // sum(len(b) for b in blocks), *vals)
"#;

#[test]
fn vtu_round_trips_through_meshio() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("mixed.vtu");
    let m = mixed();
    write_mixed(&path, &m);
    let Some(out) = run_python("meshio", MESHIO_DUMP, &[&path]) else {
        return;
    };
    let floats =
        |xs: &[&str]| -> Vec<f64> { xs.iter().map(|x| x.parse().expect("float")).collect() };
    let mut cells = Vec::new();
    let mut seen = 0;
    for line in out.lines() {
        let f: Vec<&str> = line.split(' ').collect();
        match f[0] {
            "points" => assert_eq!(
                floats(&f[1..]),
                m.points.iter().flatten().copied().collect::<Vec<_>>()
            ),
            "cells" => {
                let n = match f[1] {
                    "hexahedron" => 8,
                    "tetra" => 4,
                    "quad" => 4,
                    "triangle" => 3,
                    "line" => 2,
                    other => panic!("unexpected meshio cell type {other}"),
                };
                let conn: Vec<usize> = f[2..].iter().map(|x| x.parse().expect("int")).collect();
                cells.extend(conn.chunks(n).map(|c| (f[1].to_string(), c.to_vec())));
            }
            "point" | "cell" => {
                let comps: usize = f[2].parse().expect("components");
                let vals = floats(&f[3..]);
                let (want_comps, want) = match f[1] {
                    "displacement" => (3, &m.u),
                    "pressure_<p>_&_\"q\"" => (1, &m.p),
                    "id" => (1, &m.id),
                    "stress" => (9, &m.stress),
                    other => panic!("unexpected array {other}"),
                };
                assert_eq!((comps, &vals), (want_comps, want), "{}", f[1]);
                seen += 1;
            }
            other => panic!("unexpected line {other}"),
        }
    }
    assert_eq!(seen, 4, "all four fields came back");
    let names = ["hexahedron", "tetra", "quad", "triangle", "line"];
    assert_eq!(cells.len(), m.cells.len());
    for ((name, conn), (_, want)) in cells.iter().zip(&m.cells) {
        assert!(names.contains(&name.as_str()));
        assert_eq!(conn, want);
    }
    eprintln!("meshio read the .vtu back: points, cells and 4 fields identical");
}

/// VTK's own cell volumes/areas for a .vtu: "n_cells sum min" per cell dimension.
const PYVISTA_SIZES: &str = r#"
import sys, pyvista as pv
g = pv.read(sys.argv[1])
s = g.compute_cell_sizes(length=False, area=True, volume=True)
import numpy as np
dims = np.array([g.get_cell(i).dimension for i in range(g.n_cells)])
for d, key in [(2, "Area"), (3, "Volume")]:
    v = s.cell_data[key][dims == d]
    if len(v): print(d, len(v), repr(float(v.sum())), repr(float(v.min())))
"#;

fn fixture(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(format!("fixtures/meshes/{name}.msh"))
}

#[test]
fn gmsh_node_order_is_vtk_node_order() {
    // Gmsh meshes written unchanged must have positive VTK volumes summing to the box volume.
    let dir = tempfile::tempdir().expect("tempdir");
    for case in [
        "box_tet4_v41_bin",
        "box_hex8_v22_ascii",
        "square_quad4_v41_ascii",
        "square_tri3_sparse_v22_bin",
    ] {
        let mesh = read_gmsh(&fixture(case)).expect("fixture");
        let top = mesh.highest_dimension().expect("elements");
        let cells: Vec<(VtkCellKind, &[usize])> = mesh
            .elements
            .iter()
            .filter(|e| e.kind.dimension() == Some(top))
            .map(|e| {
                let kind = match e.kind {
                    GmshCellKind::Tri3 => VtkCellKind::Tri3,
                    GmshCellKind::Quad4 => VtkCellKind::Quad4,
                    GmshCellKind::Tet4 => VtkCellKind::Tet4,
                    GmshCellKind::Hex8 => VtkCellKind::Hex8,
                    other => panic!("unexpected {other:?}"),
                };
                (kind, e.nodes.as_slice())
            })
            .collect();
        let path = dir.path().join(format!("{case}.vtu"));
        let piece = VtkPiece {
            points: &mesh.nodes,
            cells: &cells,
            point_data: &[],
            cell_data: &[],
        };
        write_vtu(&path, &piece).expect("write");
        let Some(out) = run_python("pyvista", PYVISTA_SIZES, &[&path]) else {
            return;
        };
        let f: Vec<&str> = out.split_whitespace().collect();
        assert_eq!(f.len(), 4, "{out}");
        let (n, sum, min): (usize, f64, f64) = (
            f[1].parse().expect("n"),
            f[2].parse().expect("sum"),
            f[3].parse().expect("min"),
        );
        let size = if top == 3 { 2.0 * 1.0 * 0.5 } else { 2.0 * 1.0 };
        assert_eq!(n, cells.len());
        assert!(
            (sum - size).abs() < 1e-9,
            "{case}: VTK measure {sum} vs {size}"
        );
        // vtkCellSizeFilter reports signed volumes: an inverted cell would be negative.
        assert!(min > 0.0, "{case}: VTK found a cell of measure {min}");
    }
}

#[test]
fn vtk_reports_inverted_cells_negative() {
    // Guard for the test above: VTK must see a mirrored tetrahedron as negative.
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("inverted.vtu");
    let points = [[0., 0., 0.], [1., 0., 0.], [0., 1., 0.], [0., 0., 1.]];
    let cells: [(VtkCellKind, &[usize]); 1] = [(VtkCellKind::Tet4, &[0, 2, 1, 3])];
    let piece = VtkPiece {
        points: &points,
        cells: &cells,
        point_data: &[],
        cell_data: &[],
    };
    write_vtu(&path, &piece).expect("write");
    let Some(out) = run_python("pyvista", PYVISTA_SIZES, &[&path]) else {
        return;
    };
    let min: f64 = out
        .split_whitespace()
        .nth(3)
        .expect("min")
        .parse()
        .expect("float");
    assert!(min < 0.0, "VTK volume of an inverted tet: {min}");
}

#[test]
fn pvd_opens_in_pyvista() {
    let dir = tempfile::tempdir().expect("tempdir");
    let m = mixed();
    std::fs::create_dir(dir.path().join("frames")).expect("mkdir");
    let mut entries = Vec::new();
    for k in 0..3 {
        let rel = format!("frames/step_{k:04}.vtu");
        write_mixed(&dir.path().join(&rel), &m);
        entries.push((0.25 * k as f64, rel));
    }
    let pvd = dir.path().join("run.pvd");
    write_pvd(&pvd, &entries).expect("pvd");
    let script = r#"
import sys, pyvista as pv
r = pv.get_reader(sys.argv[1])
print(" ".join(repr(float(t)) for t in r.time_values))
r.set_active_time_value(r.time_values[-1])
print(r.read()[0].n_cells)
"#;
    let Some(out) = run_python("pyvista", script, &[&pvd]) else {
        return;
    };
    let mut lines = out.lines();
    assert_eq!(lines.next(), Some("0.0 0.25 0.5"));
    assert_eq!(lines.next(), Some("5"));
}
