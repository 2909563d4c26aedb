//! Wavefront OBJ reading: vertices, faces (fan-triangulated), polylines and points, with the
//! file's own vertex numbering.
//!
//! Our own reader rather than `tobj`: with separate index lists tobj renumbers the vertices in
//! the order faces first use them and drops the ones no face uses, so `l` polylines (which it
//! turns into polygons), `p` points and pin indices would no longer match the file. Here
//! vertex `k` of the file is particle `k` of the object, always.
//!
//! Read: `v x y z [w]` (`w` ignored), `f`, `l`, `p` with 1-based or negative (relative)
//! indices in any of the `v`, `v/vt`, `v//vn`, `v/vt/vn` forms. Ignored: `vt`, `vn`, `vp`,
//! `o`, `g`, `s`, `usemtl`, `mtllib`, comments and blank lines. Anything else is an error
//! naming its line, as is an index out of range, a face that repeats a vertex, or a line that
//! repeats one back to back (a closed polyline `l 1 2 3 1` is fine).

use std::path::Path;

use crate::scene::Geometry;

/// Reads the OBJ file at `path`, scaled by `scale` and then translated by `translate`.
pub fn load_obj(path: &Path, scale: f64, translate: [f64; 3]) -> Result<Geometry, String> {
    let text = std::fs::read_to_string(path).map_err(|e| e.to_string())?;
    let mut geo = parse_obj(&text)?;
    for p in &mut geo.positions {
        for k in 0..3 {
            p[k] = p[k] * scale + translate[k];
        }
        if !p.iter().all(|c| c.is_finite()) {
            return Err("a vertex position is not finite after scaling".into());
        }
    }
    Ok(geo)
}

/// Parses OBJ text: triangles from faces (fanned from their first vertex), curve edges from
/// polylines, and isolated points from `p` elements and from vertices nothing else uses.
pub fn parse_obj(text: &str) -> Result<Geometry, String> {
    let mut geo = Geometry::default();
    for (k, raw) in text.lines().enumerate() {
        let at = |message: String| format!("line {}: {message}", k + 1);
        let line = raw.split('#').next().unwrap_or_default();
        let mut words = line.split_whitespace();
        let Some(tag) = words.next() else { continue };
        match tag {
            "v" => {
                let coords: Vec<f64> = words
                    .map(|w| {
                        w.parse::<f64>()
                            .map_err(|_| at(format!("bad number `{w}`")))
                    })
                    .collect::<Result<_, _>>()?;
                if !(3..=4).contains(&coords.len()) {
                    return Err(at(format!(
                        "a vertex has 3 coordinates, found {}",
                        coords.len()
                    )));
                }
                if !coords[..3].iter().all(|c| c.is_finite()) {
                    return Err(at("non-finite vertex position".into()));
                }
                geo.positions.push([coords[0], coords[1], coords[2]]);
            }
            "f" | "l" | "p" => {
                let n = geo.positions.len();
                let ids: Vec<u32> = words
                    .map(|w| index(w, n).map_err(&at))
                    .collect::<Result<_, _>>()?;
                let least = match tag {
                    "f" => 3,
                    "l" => 2,
                    _ => 1,
                };
                if ids.len() < least {
                    return Err(at(format!(
                        "`{tag}` needs at least {least} vertices, found {}",
                        ids.len()
                    )));
                }
                match tag {
                    "f" => {
                        let mut sorted = ids.clone();
                        sorted.sort_unstable();
                        if let Some(w) = sorted.windows(2).find(|w| w[0] == w[1]) {
                            return Err(at(format!("`f` repeats vertex {}", w[0] + 1)));
                        }
                        for w in ids[1..].windows(2) {
                            geo.triangles.push([ids[0], w[0], w[1]]);
                        }
                    }
                    "l" => {
                        // A closed polyline (`l 1 2 3 1`) may come back to its start, but a
                        // segment needs two distinct ends.
                        if let Some(w) = ids.windows(2).find(|w| w[0] == w[1]) {
                            return Err(at(format!(
                                "`l` repeats vertex {} back to back",
                                w[0] + 1
                            )));
                        }
                        geo.edges.extend(ids.windows(2).map(|w| [w[0], w[1]]));
                    }
                    // A vertex no face or line uses is an isolated point anyway.
                    _ => {}
                }
            }
            "vt" | "vn" | "vp" | "o" | "g" | "s" | "usemtl" | "mtllib" => {}
            other => return Err(at(format!("unknown OBJ statement `{other}`"))),
        }
    }
    if geo.positions.is_empty() {
        return Err("the file has no vertices".into());
    }
    let mut used = vec![false; geo.positions.len()];
    for &i in geo
        .triangles
        .iter()
        .flatten()
        .chain(geo.edges.iter().flatten())
    {
        used[i as usize] = true;
    }
    geo.points = (0..used.len() as u32)
        .filter(|&i| !used[i as usize])
        .collect();
    Ok(geo)
}

/// The 0-based vertex index of an element word (`v`, `v/vt`, `v//vn`, `v/vt/vn`), with `n`
/// vertices read so far (negative indices count back from the last).
fn index(word: &str, n: usize) -> Result<u32, String> {
    let first = word.split('/').next().unwrap_or_default();
    let i: i64 = first
        .parse()
        .map_err(|_| format!("bad vertex index `{word}`"))?;
    let k = if i < 0 { n as i64 + i } else { i - 1 };
    if i == 0 || k < 0 || k >= n as i64 {
        return Err(format!(
            "vertex index {i} is out of range ({n} vertices so far)"
        ));
    }
    Ok(k as u32)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn polylines_keep_the_files_numbering_and_become_edges() {
        let g = parse_obj("v 0 0 0\nv 1 0 0\nv 2 0 0\nv 3 1 0\nl 1 2 3 4\n").unwrap();
        assert_eq!(g.positions.len(), 4);
        assert_eq!(g.edges, vec![[0, 1], [1, 2], [2, 3]]);
        assert!(g.triangles.is_empty() && g.points.is_empty());
        assert_eq!(g.positions[3], [3.0, 1.0, 0.0]);
    }

    #[test]
    fn faces_are_fanned_and_unused_vertices_are_points() {
        // Vertex 1 (0-based 0) is used by nothing; the quad uses 2..5, listed out of order.
        let g = parse_obj(
            "# a quad and a spare vertex\nv 9 9 9\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n\
             vn 0 0 1\nf 5//1 2//1 3//1 4//1\n",
        )
        .unwrap();
        assert_eq!(g.triangles, vec![[4, 1, 2], [4, 2, 3]]);
        assert_eq!(g.points, vec![0]);
        assert_eq!(g.positions[0], [9.0, 9.0, 9.0]);
    }

    #[test]
    fn mixed_files_give_triangles_curves_and_points_together() {
        let g = parse_obj(
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nv 0 0 2\nv 5 5 5\n\
             f 1/1 2/2 3/3\nl -3 -2\np 6\n",
        )
        .unwrap();
        assert_eq!(g.triangles, vec![[0, 1, 2]]);
        // `-3 -2` after six vertices are vertices 4 and 5 (1-based).
        assert_eq!(g.edges, vec![[3, 4]]);
        assert_eq!(g.points, vec![5]);
    }

    #[test]
    fn a_closed_polyline_comes_back_to_its_start() {
        let g = parse_obj("v 0 0 0\nv 1 0 0\nv 0 1 0\nl 1 2 3 1\n").unwrap();
        assert_eq!(g.edges, vec![[0, 1], [1, 2], [2, 0]]);
    }

    #[test]
    fn bad_files_name_the_line() {
        let cases = [
            ("v 0 0\n", "line 1: a vertex has 3 coordinates"),
            ("v 0 0 x\n", "line 1: bad number `x`"),
            (
                "v 0 0 0\nv 1 0 0\nf 1 2 3\n",
                "line 3: vertex index 3 is out of range",
            ),
            (
                "v 0 0 0\nf 0 1 1\n",
                "line 2: vertex index 0 is out of range",
            ),
            (
                "v 0 0 0\nv 1 0 0\nl 1 1 2\n",
                "line 3: `l` repeats vertex 1 back to back",
            ),
            (
                "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3 1\n",
                "line 4: `f` repeats vertex 1",
            ),
            ("v 0 0 0\nl 1\n", "line 2: `l` needs at least 2 vertices"),
            (
                "v 0 0 0\ncurv 0 1 1\n",
                "line 2: unknown OBJ statement `curv`",
            ),
            ("# nothing\n", "the file has no vertices"),
            ("v 0 0 nan\n", "line 1: non-finite vertex position"),
        ];
        for (text, expected) in cases {
            let err = parse_obj(text).expect_err(text);
            assert!(err.starts_with(expected), "{text:?}: {err}");
        }
    }
}
