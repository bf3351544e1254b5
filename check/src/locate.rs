//! Finds the line and column of a field path in YAML text, for problems found after parsing
//! (ranges, cross-field checks). Handles block mappings, block sequences and one-line flow
//! collections, which is how configs are written; returns None when it cannot tell, and the error
//! then names the file and field only.

use crate::Seg;

struct Line<'a> {
    text: &'a str,
    indent: usize,
}

fn lines(text: &str) -> Vec<Line<'_>> {
    text.lines()
        .map(|l| {
            let code = if l.trim_start().starts_with('#') { "" } else { l.find(" #").map_or(l, |p| &l[..p]) };
            Line { text: code, indent: code.len() - code.trim_start().len() }
        })
        .collect()
}

/// Column (0-based) where the node of a line starts after any `- ` sequence markers.
fn node_start(l: &str) -> usize {
    let mut i = l.len() - l.trim_start().len();
    while l[i..].starts_with("- ") {
        i += 2;
        i += l[i..].len() - l[i..].trim_start().len();
    }
    i
}

/// 1-based (line, column) of the last segment of `path`: the path is followed one segment at a
/// time, each found inside the lines of the node the previous one named.
pub fn locate(text: &str, path: &[Seg]) -> Option<(usize, usize)> {
    let ls = lines(text);
    let mut node = Node { from: 0, to: ls.len(), col: -1 };
    let mut at = None;
    for (depth, seg) in path.iter().enumerate() {
        let (i, c) = match seg {
            // Keys of a mapping inside a sequence item start at the item's own column.
            Seg::Key(k) => find_key(&ls, &node, k.as_ref(), depth > 0 && matches!(path[depth - 1], Seg::Index(_)), depth == 0)?,
            Seg::Index(n) => match find_item(&ls, &node, *n) {
                Some(hit) => hit,
                // A flow sequence `[a, b]` on the parent's line: point at the parent.
                None => return at,
            },
        };
        at = Some((i + 1, c + 1));
        if depth + 1 < path.len() {
            node = Node { from: i, to: extent(&ls, i, c, node.to, seg), col: c as isize };
        }
    }
    at
}

/// The node being searched: lines [from, to), whose direct children sit at columns > `col` (or at
/// `col` itself for a block sequence written under its key).
struct Node {
    from: usize,
    to: usize,
    col: isize,
}

/// The line and column (0-based) of key `k` among the children of `node`: a block mapping's key
/// (`after_item`: the first key of a mapping that is a sequence item, at the item's column; `top`:
/// a key of the document at column 0), the shallowest one where a deeper mapping in the node has
/// the same key (`optical:` of a section and of its sensor rules); else a key of a one-line flow
/// mapping.
fn find_key(ls: &[Line], node: &Node, k: &str, after_item: bool, top: bool) -> Option<(usize, usize)> {
    let block = (node.from..node.to)
        .filter_map(|i| {
            let l = ls[i].text;
            let s = node_start(l);
            let deeper = s as isize > node.col || (after_item && s as isize == node.col) || (top && s == 0);
            (deeper && l[s..].starts_with(&format!("{k}:"))).then_some((i, s))
        })
        .min_by_key(|&(i, s)| (s, i));
    block.or_else(|| {
        (node.from..node.to).find_map(|i| {
            // A one-line flow mapping: `parent: {a: 1, k: 2}`.
            let l = ls[i].text;
            let open = l.find('{')?;
            [format!("{{{k}:"), format!(" {k}:"), format!(",{k}:")]
                .iter()
                .find_map(|p| l[open..].find(p.as_str()).map(|q| (i, open + q + p.len() - k.len() - 1)))
        })
    })
}

/// The line and column (0-based) of block sequence item `n` in `node`: the `n`-th `- ` at the
/// first dash indent found there.
fn find_item(ls: &[Line], node: &Node, n: usize) -> Option<(usize, usize)> {
    let dashes: Vec<(usize, usize)> = (node.from..node.to)
        .filter(|&i| ls[i].text.trim_start().starts_with("- ") && ls[i].indent as isize >= node.col)
        .map(|i| (i, ls[i].indent))
        .collect();
    let first = dashes.first().map(|d| d.1);
    dashes.into_iter().filter(|d| Some(d.1) == first).nth(n).map(|(i, ind)| (i, ind + 2))
}

/// The end (exclusive, at most `to`) of the node `seg` found at line `i`, column `c`: its own line
/// plus the following lines indented deeper than it (or block-sequence dashes at its own indent,
/// `key:\n- a`).
fn extent(ls: &[Line], i: usize, c: usize, to: usize, seg: &Seg) -> usize {
    let mut j = i + 1;
    while j < to {
        let l = &ls[j];
        let deeper = match seg {
            Seg::Key(_) => l.indent > c || (l.indent == c && l.text.trim_start().starts_with("- ")),
            // The item's mapping continues at the column its first key started.
            Seg::Index(_) => l.indent >= c,
        };
        if !l.text.trim().is_empty() && !deeper {
            break;
        }
        j += 1;
    }
    j
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::display_path;

    const YAML: &str = "seed: 1\nobjects:\n  - 003_cracker_box\n  - id: custom\n    mesh: a.obj\ncamera:\n  width: 640\n  intrinsics: {fx: 600, fy: 610, cx: 1, cy: 2}\n  near: 0.1 # comment\nscene:\n  workspace:\n    min: [0, 0, 0]\n";

    #[test]
    fn finds_block_flow_and_sequence_fields() {
        assert_eq!(locate(YAML, &[Seg::key("seed")]), Some((1, 1)));
        assert_eq!(locate(YAML, &[Seg::key("camera"), Seg::key("near")]), Some((9, 3)));
        assert_eq!(locate(YAML, &[Seg::key("camera"), Seg::key("intrinsics"), Seg::key("fy")]), Some((8, 25)));
        assert_eq!(locate(YAML, &[Seg::key("objects"), Seg::Index(1)]), Some((4, 5)));
        assert_eq!(locate(YAML, &[Seg::key("objects"), Seg::Index(1), Seg::key("mesh")]), Some((5, 5)));
        assert_eq!(locate(YAML, &[Seg::key("scene"), Seg::key("workspace"), Seg::key("min")]), Some((12, 5)));
        assert_eq!(locate(YAML, &[Seg::key("camera"), Seg::key("far")]), None);
        // A key of a section found at the section's own level, not in a deeper mapping before it.
        let nested = "robot:\n  tactile:\n    sensors:\n      - pads: a\n        optical:\n          noise_std: 1\n    optical:\n      noise_std: 2\n";
        assert_eq!(locate(nested, &[Seg::key("robot"), Seg::key("tactile"), Seg::key("optical"), Seg::key("noise_std")]), Some((8, 7)));
        assert_eq!(display_path(&[Seg::key("objects"), Seg::Index(1), Seg::key("mesh")]), "objects[1].mesh");
    }
}
