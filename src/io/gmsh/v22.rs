//! MSH 2.2, ASCII and binary, parsed by hand (`mshio` only knows 4.1).

use std::collections::HashMap;

use super::cursor::{parse_tok, show, Cursor};
use super::header::{parse_physical_names, MeshFormat};
use super::{insert_node, type_info, GmshCellKind, GmshElement, GmshError, GmshMesh};

pub(super) fn parse_v22(mut cur: Cursor<'_>, header: &MeshFormat) -> Result<GmshMesh, GmshError> {
    let mut mesh = GmshMesh::default();
    let mut tag_to_index: Option<HashMap<usize, usize>> = None;
    let mut seen_elements = false;
    while let Some((name, at)) = cur.next_section()? {
        match name.as_str() {
            "PhysicalNames" => mesh.physical_names.extend(parse_physical_names(&mut cur)?),
            "Nodes" => {
                if tag_to_index.is_some() {
                    return Err(cur.err(at, show(b"$Nodes"), "a single $Nodes section"));
                }
                let (nodes, map) = if header.binary {
                    v22_nodes_binary(&mut cur)?
                } else {
                    v22_nodes_ascii(&mut cur)?
                };
                mesh.nodes = nodes;
                tag_to_index = Some(map);
                cur.expect_end("Nodes")?;
            }
            "Elements" => {
                let map = tag_to_index
                    .as_ref()
                    .ok_or_else(|| cur.err(at, show(b"$Elements"), "$Nodes before $Elements"))?;
                if seen_elements {
                    return Err(cur.err(at, show(b"$Elements"), "a single $Elements section"));
                }
                seen_elements = true;
                mesh.elements = if header.binary {
                    v22_elements_binary(&mut cur, map)?
                } else {
                    v22_elements_ascii(&mut cur, map)?
                };
                cur.expect_end("Elements")?;
            }
            // $NodeData, $Periodic, $Comments, ...: not needed for the geometry.
            other => cur.skip_section(other)?,
        }
    }
    if tag_to_index.is_none() {
        return Err(GmshError::MissingSection {
            section: "$Nodes".into(),
        });
    }
    if !seen_elements {
        return Err(GmshError::MissingSection {
            section: "$Elements".into(),
        });
    }
    Ok(mesh)
}

/// The count line that opens `$Nodes` / `$Elements`.
fn count_line(cur: &mut Cursor<'_>, section: &str, what: &str) -> Result<usize, GmshError> {
    // The count is ASCII even in binary files.
    let (line, at) = cur.section_line(section, what)?;
    parse_tok(line).ok_or_else(|| GmshError::Parse {
        line: cur.line_of(at),
        found: show(line),
        expected: what.to_string(),
    })
}

/// Capacity hint bounded by the input size, so a corrupt count cannot trigger a huge allocation.
fn capacity(count: usize, remaining: usize, min_record: usize) -> usize {
    count.min(remaining / min_record.max(1))
}

type NodesAndMap = (Vec<[f64; 3]>, HashMap<usize, usize>);

fn v22_nodes_ascii(cur: &mut Cursor<'_>) -> Result<NodesAndMap, GmshError> {
    const SEC: &str = "$Nodes";
    let n = count_line(cur, SEC, "the number of nodes")?;
    let cap = capacity(n, cur.b.len() - cur.pos, 8);
    let mut nodes = Vec::with_capacity(cap);
    let mut map = HashMap::with_capacity(cap);
    for i in 0..n {
        let expected = "a node line \"tag x y z\"";
        let (line, at) = cur.section_line(SEC, "the remaining node lines")?;
        let toks: Vec<&[u8]> = line
            .split(u8::is_ascii_whitespace)
            .filter(|t| !t.is_empty())
            .collect();
        if toks.len() != 4 {
            return Err(cur.err(at, show(line), expected));
        }
        let tag: usize = parse_tok(toks[0])
            .ok_or_else(|| cur.err(at, show(toks[0]), "a non-negative integer node tag"))?;
        let mut x = [0.0; 3];
        for (k, t) in toks[1..].iter().enumerate() {
            x[k] = parse_tok::<f64>(t)
                .filter(|v| v.is_finite())
                .ok_or_else(|| cur.err(at, show(t), "a finite coordinate"))?;
        }
        insert_node(&mut map, tag, i)?;
        nodes.push(x);
    }
    Ok((nodes, map))
}

fn v22_nodes_binary(cur: &mut Cursor<'_>) -> Result<NodesAndMap, GmshError> {
    const SEC: &str = "$Nodes";
    // Record: int tag, then x y z as doubles.
    const REC: usize = 4 + 3 * 8;
    let n = count_line(cur, SEC, "the number of nodes")?;
    let start = cur.pos;
    let data = n
        .checked_mul(REC)
        .and_then(|len| cur.take(len))
        .ok_or_else(|| cur.truncated(SEC, format!("{n} binary node records of {REC} bytes")))?;
    let mut nodes = Vec::with_capacity(n);
    let mut map = HashMap::with_capacity(n);
    for (i, rec) in data.as_chunks::<REC>().0.iter().enumerate() {
        let at = start + i * REC;
        let tag = cur.i32_at(rec);
        let tag = usize::try_from(tag).map_err(|_| GmshError::Binary {
            offset: at,
            found: format!("node tag {tag}"),
            expected: "a non-negative node tag".into(),
        })?;
        let mut x = [0.0; 3];
        for (k, v) in x.iter_mut().enumerate() {
            *v = cur.f64_at(&rec[4 + 8 * k..]);
            if !v.is_finite() {
                return Err(GmshError::Binary {
                    offset: at + 4 + 8 * k,
                    found: format!("coordinate {v}"),
                    expected: "a finite coordinate".into(),
                });
            }
        }
        insert_node(&mut map, tag, i)?;
        nodes.push(x);
    }
    Ok((nodes, map))
}

/// Build an element from 2.2 data (tags = physical, elementary, ...).
fn make_element(
    elm: usize,
    ty: i32,
    tags: &[i32],
    node_tags: impl IntoIterator<Item = usize>,
    map: &HashMap<usize, usize>,
) -> Result<GmshElement, GmshError> {
    let nodes = node_tags
        .into_iter()
        .map(|t| {
            map.get(&t).copied().ok_or(GmshError::UnknownNodeTag {
                tag: t,
                element: elm,
            })
        })
        .collect::<Result<Vec<_>, _>>()?;
    Ok(GmshElement {
        kind: GmshCellKind::from_gmsh_type(ty),
        nodes,
        physical_tag: tags.first().copied().filter(|&t| t != 0),
        entity_tag: tags.get(1).copied().unwrap_or(0),
        tag: elm,
    })
}

fn v22_elements_ascii(
    cur: &mut Cursor<'_>,
    map: &HashMap<usize, usize>,
) -> Result<Vec<GmshElement>, GmshError> {
    const SEC: &str = "$Elements";
    let n = count_line(cur, SEC, "the number of elements")?;
    let mut elements = Vec::with_capacity(capacity(n, cur.b.len() - cur.pos, 8));
    for _ in 0..n {
        let (line, at) = cur.section_line(SEC, "the remaining element lines")?;
        let toks: Vec<&[u8]> = line
            .split(u8::is_ascii_whitespace)
            .filter(|t| !t.is_empty())
            .collect();
        let shape = "an element line \"number type ntags tags... nodes...\"";
        if toks.len() < 3 {
            return Err(cur.err(at, show(line), shape));
        }
        let elm: usize = parse_tok(toks[0])
            .ok_or_else(|| cur.err(at, show(toks[0]), "a non-negative element number"))?;
        let ty: i32 = parse_tok(toks[1])
            .ok_or_else(|| cur.err(at, show(toks[1]), "an integer element type"))?;
        let ntags: usize = parse_tok(toks[2])
            .filter(|&k| k <= toks.len() - 3)
            .ok_or_else(|| {
                cur.err(
                    at,
                    show(toks[2]),
                    "the number of tags that follow on the line",
                )
            })?;
        let tags = toks[3..3 + ntags]
            .iter()
            .map(|t| parse_tok::<i32>(t).ok_or_else(|| cur.err(at, show(t), "an integer tag")))
            .collect::<Result<Vec<_>, _>>()?;
        let node_toks = &toks[3 + ntags..];
        // Unknown types are taken as given: their node count is whatever the line holds.
        let expected_nodes = type_info(ty).map_or(node_toks.len().max(1), |(k, _)| k);
        if node_toks.len() != expected_nodes {
            return Err(cur.err(
                at,
                format!("{} node tags", node_toks.len()),
                format!("{expected_nodes} node tags for element type {ty}"),
            ));
        }
        let node_tags = node_toks
            .iter()
            .map(|t| {
                parse_tok::<usize>(t).ok_or_else(|| cur.err(at, show(t), "a non-negative node tag"))
            })
            .collect::<Result<Vec<_>, _>>()?;
        elements.push(make_element(elm, ty, &tags, node_tags, map)?);
    }
    Ok(elements)
}

fn v22_elements_binary(
    cur: &mut Cursor<'_>,
    map: &HashMap<usize, usize>,
) -> Result<Vec<GmshElement>, GmshError> {
    const SEC: &str = "$Elements";
    let n = count_line(cur, SEC, "the number of elements")?;
    let mut elements = Vec::with_capacity(capacity(n, cur.b.len() - cur.pos, 12));
    // Blocks of elements of one type: header (type, count, ntags), then the records.
    while elements.len() < n {
        let at = cur.pos;
        let head = cur
            .take(12)
            .ok_or_else(|| cur.truncated(SEC, format!("{} more elements", n - elements.len())))?;
        let (ty, count, ntags) = (
            cur.i32_at(head),
            cur.i32_at(&head[4..]),
            cur.i32_at(&head[8..]),
        );
        let left = n - elements.len();
        let count = usize::try_from(count)
            .ok()
            .filter(|&c| c >= 1 && c <= left)
            .ok_or_else(|| GmshError::Binary {
                offset: at + 4,
                found: format!("block of {count} elements"),
                expected: format!("between 1 and {left} elements (the rest of $Elements)"),
            })?;
        let ntags = usize::try_from(ntags).map_err(|_| GmshError::Binary {
            offset: at + 8,
            found: format!("{ntags} tags"),
            expected: "a non-negative number of tags".into(),
        })?;
        let (nn, _) = type_info(ty).ok_or_else(|| GmshError::Binary {
            offset: at,
            found: format!("element type {ty}"),
            expected: "an element type with a known node count (1 to 31)".into(),
        })?;
        let rec_ints = 1 + ntags + nn;
        let start = cur.pos;
        let data = rec_ints
            .checked_mul(4)
            .and_then(|x| x.checked_mul(count))
            .and_then(|len| cur.take(len))
            .ok_or_else(|| cur.truncated(SEC, format!("{count} element records of type {ty}")))?;
        for (k, rec) in data.chunks_exact(4 * rec_ints).enumerate() {
            let ints: Vec<i32> = rec
                .as_chunks::<4>()
                .0
                .iter()
                .map(|c| cur.i32_at(c))
                .collect();
            let rec_at = start + k * 4 * rec_ints;
            let elm = usize::try_from(ints[0]).map_err(|_| GmshError::Binary {
                offset: rec_at,
                found: format!("element number {}", ints[0]),
                expected: "a non-negative element number".into(),
            })?;
            let node_tags = ints[1 + ntags..]
                .iter()
                .enumerate()
                .map(|(j, &t)| {
                    usize::try_from(t).map_err(|_| GmshError::Binary {
                        offset: rec_at + 4 * (1 + ntags + j),
                        found: format!("node tag {t}"),
                        expected: "a non-negative node tag".into(),
                    })
                })
                .collect::<Result<Vec<_>, _>>()?;
            elements.push(make_element(elm, ty, &ints[1..1 + ntags], node_tags, map)?);
        }
    }
    Ok(elements)
}
