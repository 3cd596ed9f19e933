//! MSH 4.1, ASCII and binary, through the `mshio` crate: this module finds the sections,
//! reads `$PhysicalNames` (which `mshio` 0.4 skips), keeps the node tags of contiguously
//! numbered files, catches `mshio` panics and maps its errors back to lines and offsets.

use std::collections::HashMap;

use super::cursor::{parse_tok, show, show_hex, Cursor};
use super::header::{parse_physical_names, MeshFormat};
use super::{insert_node, GmshCellKind, GmshElement, GmshError, GmshMesh};

/// Where the four header numbers of `$Nodes` or `$Elements` are, and their values.
struct BlockHeader {
    /// Byte range of the 4th number (max tag) in the file.
    max_tag: std::ops::Range<usize>,
    /// Total number of nodes or elements.
    count: u64,
}

/// Read `numEntityBlocks numX minTag maxTag` at the start of a 4.1 `$Nodes`/`$Elements`.
fn v41_block_header(
    cur: &Cursor<'_>,
    content: usize,
    header: &MeshFormat,
    section: &str,
) -> Result<BlockHeader, GmshError> {
    let mut c = cur.clone();
    c.pos = content;
    let mut values = [0u64; 4];
    let mut last = 0..0;
    if header.binary {
        let ds = header.data_size;
        for v in &mut values {
            let at = c.pos;
            let b = c.take(ds).ok_or_else(|| {
                c.truncated(section, "the four size_t numbers of the section header")
            })?;
            *v = c.uint_at(b, ds);
            last = at..at + ds;
        }
    } else {
        for v in &mut values {
            let (tok, at) = c
                .token()
                .ok_or_else(|| c.truncated(section, "the four numbers of the section header"))?;
            *v = parse_tok(tok).ok_or_else(|| {
                c.err(
                    at,
                    show(tok),
                    format!("a non-negative integer in the {section} header"),
                )
            })?;
            last = at..at + tok.len();
        }
    }
    if values[1] == 0 {
        // mshio 0.4 underflows (panics) on empty sections, so refuse them here.
        return Err(c.err(
            content,
            format!("{section} with 0 entries"),
            format!("a non-empty {section} section"),
        ));
    }
    Ok(BlockHeader {
        max_tag: last,
        count: values[1],
    })
}

pub(super) fn parse_v41(mut cur: Cursor<'_>, header: &MeshFormat) -> Result<GmshMesh, GmshError> {
    let mut physical_names = Vec::new();
    let mut nodes_content = None;
    let mut elements_content = None;
    // Walk the sections: $PhysicalNames is ours (mshio skips it); the rest is left to mshio,
    // but we need the position of the $Nodes header to patch it (see below).
    while let Some((name, at)) = cur.next_section()? {
        let content = cur.pos;
        let slot = match name.as_str() {
            "PhysicalNames" => {
                physical_names.extend(parse_physical_names(&mut cur)?);
                continue;
            }
            "Nodes" => &mut nodes_content,
            "Elements" => &mut elements_content,
            _ => {
                cur.skip_section(&name)?;
                continue;
            }
        };
        if slot.is_some() {
            return Err(cur.err(
                at,
                show(name.as_bytes()),
                format!("a single ${name} section"),
            ));
        }
        *slot = Some(content);
        cur.skip_section(&name)?;
    }
    let nodes_content = nodes_content.ok_or(GmshError::MissingSection {
        section: "$Nodes".into(),
    })?;
    let elements_content = elements_content.ok_or(GmshError::MissingSection {
        section: "$Elements".into(),
    })?;
    let nodes_header = v41_block_header(&cur, nodes_content, header, "$Nodes")?;
    let elements_header = v41_block_header(&cur, elements_content, header, "$Elements")?;

    // mshio 0.4 drops the node tags when they are contiguous (max - min + 1 == count) and then
    // assumes file order == tag order, which Gmsh does not promise. Declaring the largest
    // possible max tag makes it keep every tag; the value is not used otherwise.
    let mut patched: Vec<u8> = Vec::with_capacity(cur.b.len() + 24);
    let r = nodes_header.max_tag.clone();
    patched.extend_from_slice(&cur.b[header.start..r.start]);
    let shift: isize;
    if header.binary {
        patched.extend(std::iter::repeat_n(0xff_u8, r.len()));
        shift = 0;
    } else {
        let text = u64::MAX.to_string();
        shift = text.len() as isize - r.len() as isize;
        patched.extend_from_slice(text.as_bytes());
    }
    patched.extend_from_slice(&cur.b[r.end..]);
    // Map an offset in `patched` back to the original file.
    let original = |p: usize| -> usize {
        let p = p + header.start;
        if p > r.start {
            (p as isize - shift).max(r.start as isize) as usize
        } else {
            p
        }
    };

    let parsed = std::panic::catch_unwind(|| {
        mshio::parse_msh_bytes(&patched).map_err(|e| describe_mshio_error(&e, &patched))
    });
    let msh = match parsed {
        Ok(Ok(msh)) => msh,
        Ok(Err((pos, found, expected))) => {
            let offset = original(pos);
            if pos >= patched.len() {
                return Err(GmshError::Truncated {
                    section: expected.split(" > ").next().unwrap_or("").to_string(),
                    offset,
                    expected,
                });
            }
            return Err(cur.err(offset, found, expected));
        }
        Err(payload) => {
            let message = payload
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| payload.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "unknown panic".to_string());
            return Err(GmshError::ParserPanic { message });
        }
    };
    convert_v41(msh, physical_names, &nodes_header, &elements_header)
}

/// (offset in the parsed buffer, found, expected) for an mshio error.
fn describe_mshio_error(e: &mshio::MshParserError<&[u8]>, buf: &[u8]) -> (usize, String, String) {
    let base = buf.as_ptr() as usize;
    // The first backtrace entry is where parsing failed; later ones are enclosing contexts.
    let pos = e
        .backtrace
        .first()
        .map_or(0, |(i, _)| (i.as_ptr() as usize).saturating_sub(base))
        .min(buf.len());
    let rest = &buf[pos..];
    let line_end = rest.iter().position(|&c| c == b'\n').unwrap_or(rest.len());
    let found = if rest.is_empty() {
        "end of file".to_string()
    } else {
        // Binary or text, show a little of what is there.
        let snippet = &rest[..line_end.clamp(1, 40)];
        if snippet.iter().all(|c| c.is_ascii_graphic() || *c == b' ') {
            show(snippet)
        } else {
            show_hex(rest)
        }
    };
    let mut parts: Vec<String> = e
        .backtrace
        .iter()
        .rev()
        .filter(|(_, k)| !k.is_nom_error())
        .map(|(_, k)| k.to_string())
        .collect();
    parts.dedup();
    let expected = if parts.is_empty() {
        "valid MSH 4.1 content".to_string()
    } else {
        parts.join(" > ")
    };
    (pos, found, expected)
}

fn convert_v41(
    msh: mshio::MshFile<u64, i32, f64>,
    physical_names: Vec<(i32, i32, String)>,
    nodes_header: &BlockHeader,
    elements_header: &BlockHeader,
) -> Result<GmshMesh, GmshError> {
    let nodes_sec = msh.data.nodes.ok_or(GmshError::MissingSection {
        section: "$Nodes".into(),
    })?;
    let elements_sec = msh.data.elements.ok_or(GmshError::MissingSection {
        section: "$Elements".into(),
    })?;

    let mut nodes = Vec::new();
    let mut tag_to_index: HashMap<usize, usize> = HashMap::new();
    for block in &nodes_sec.node_blocks {
        let tags = block.node_tags.as_ref().ok_or_else(|| GmshError::Invalid {
            found: "a node block without node tags".into(),
            expected: "mshio to keep node tags (forced by the max-tag patch)".into(),
        })?;
        // mshio stores tag -> position in block; restore position -> tag.
        let mut by_pos = vec![None; block.nodes.len()];
        for (&tag, &pos) in tags {
            let tag = usize::try_from(tag).map_err(|_| GmshError::Invalid {
                found: format!("node tag {tag}"),
                expected: "a node tag that fits in usize".into(),
            })?;
            if let Some(slot) = by_pos.get_mut(pos) {
                *slot = Some(tag);
            }
        }
        for (node, tag) in block.nodes.iter().zip(by_pos) {
            // A hole means two nodes of this block had the same tag (mshio kept only one).
            let tag = tag.ok_or_else(|| GmshError::Invalid {
                found: format!(
                    "{} distinct node tags for {} nodes in the block of entity ({}, {})",
                    tags.len(),
                    block.nodes.len(),
                    block.entity_dim,
                    block.entity_tag
                ),
                expected: "unique node tags".into(),
            })?;
            let x = [node.x, node.y, node.z];
            if x.iter().any(|v| !v.is_finite()) {
                return Err(GmshError::Invalid {
                    found: format!("node {tag} at {x:?}"),
                    expected: "finite coordinates".into(),
                });
            }
            insert_node(&mut tag_to_index, tag, nodes.len())?;
            nodes.push(x);
        }
    }
    if nodes.len() as u64 != nodes_header.count {
        return Err(GmshError::Invalid {
            found: format!("{} nodes in the node blocks", nodes.len()),
            expected: format!("{} nodes as the $Nodes header says", nodes_header.count),
        });
    }

    // Physical group of each entity: (dim, entity tag) -> first physical tag.
    let mut physical: HashMap<(i32, i32), i32> = HashMap::new();
    if let Some(ent) = &msh.data.entities {
        let mut add = |dim: i32, tag: i32, phys: &[i32]| {
            if let Some(&p) = phys.iter().find(|&&p| p != 0) {
                physical.insert((dim, tag), p);
            }
        };
        ent.points
            .iter()
            .for_each(|e| add(0, e.tag, &e.physical_tags));
        ent.curves
            .iter()
            .for_each(|e| add(1, e.tag, &e.physical_tags));
        ent.surfaces
            .iter()
            .for_each(|e| add(2, e.tag, &e.physical_tags));
        ent.volumes
            .iter()
            .for_each(|e| add(3, e.tag, &e.physical_tags));
    }

    let mut elements = Vec::new();
    for block in &elements_sec.element_blocks {
        let kind = GmshCellKind::from_gmsh_type(block.element_type as i32);
        let physical_tag = physical.get(&(block.entity_dim, block.entity_tag)).copied();
        for e in &block.elements {
            let element = usize::try_from(e.element_tag).unwrap_or(usize::MAX);
            let nodes = e
                .nodes
                .iter()
                .map(|&t| {
                    let tag = usize::try_from(t).unwrap_or(usize::MAX);
                    tag_to_index
                        .get(&tag)
                        .copied()
                        .ok_or(GmshError::UnknownNodeTag { tag, element })
                })
                .collect::<Result<Vec<_>, _>>()?;
            elements.push(GmshElement {
                kind,
                nodes,
                physical_tag,
                entity_tag: block.entity_tag,
                tag: element,
            });
        }
    }
    if elements.len() as u64 != elements_header.count {
        return Err(GmshError::Invalid {
            found: format!("{} elements in the element blocks", elements.len()),
            expected: format!(
                "{} elements as the $Elements header says",
                elements_header.count
            ),
        });
    }
    Ok(GmshMesh {
        nodes,
        elements,
        physical_names,
    })
}
