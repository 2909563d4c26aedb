//! From an object's simplicial complex to its **chambers**: the connected components of its
//! surface, each consistently oriented, with its boundary loops. Pure topology (integers),
//! done once when a group is built.
//!
//! * The surface is the object's triangles that are not inside a solid (in fewer than two
//!   tets): a shell's triangles, or the boundary faces of a tet mesh.
//! * Orientation spreads by breadth-first search over [`TrianglePair`]s (two triangles
//!   sharing an edge): a neighbour that traverses the shared edge in the same direction as
//!   the triangle it is reached from is flipped. Each component keeps the winding of its
//!   first triangle (in the object's order); [`crate::group`] then turns closed components
//!   outward. A component in which some triangle would have to be both flipped and kept (a
//!   Möbius strip, a Klein bottle) is non-orientable and refused, naming the object; so is a
//!   non-manifold surface (an edge in three or more surface triangles).
//! * Whether a component is closed comes from the complex's boundary edges
//!   ([`ObjectView::boundary_edges`]: edges in exactly one triangle), never from a user flag.
//!   The boundary edges of each component are chained into loops, each traversed in the
//!   direction its (oriented) triangles traverse it.

use std::collections::{BTreeMap, VecDeque};

use nucleus_sdk::{ObjectView, PluginError, TrianglePair};

/// One connected, consistently oriented component of an object's surface.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Chamber {
    /// Global particle indices of its vertices, ascending.
    pub vertices: Vec<u32>,
    /// Its triangles in local indices (into `vertices`), consistently oriented.
    pub triangles: Vec<[u32; 3]>,
    /// Its boundary loops, local indices, each in the direction its triangles traverse it.
    /// Empty for a closed component.
    pub loops: Vec<Vec<u32>>,
}

impl Chamber {
    /// Whether the component has no boundary.
    pub fn is_closed(&self) -> bool {
        self.loops.is_empty()
    }

    /// Reverses the orientation: every triangle and every loop.
    pub fn flip(&mut self) {
        for t in &mut self.triangles {
            t.swap(1, 2);
        }
        for l in &mut self.loops {
            l.reverse();
        }
    }
}

/// Whether the winding `t` traverses the directed edge `i → j`.
fn traverses(t: [u32; 3], i: u32, j: u32) -> bool {
    (t[0] == i && t[1] == j) || (t[1] == i && t[2] == j) || (t[2] == i && t[0] == j)
}

/// The directed edges of a winding.
fn directed_edges(t: [u32; 3]) -> [[u32; 2]; 3] {
    [[t[0], t[1]], [t[1], t[2]], [t[2], t[0]]]
}

/// The chambers of one object, in the order of their first triangle. `particles` is the
/// number of particles of the scene (indices are checked against it and the object's range).
///
/// Errors ([`PluginError::bad_object`] naming the object): a triangle outside the object's
/// particles or repeating a vertex, a non-manifold surface, a non-orientable component, or a
/// scene view whose boundary edges disagree with its triangles.
pub fn chambers(object: &ObjectView<'_>, particles: usize) -> Result<Vec<Chamber>, PluginError> {
    let name = object.name.as_str();
    let bad = |message: String| PluginError::bad_object(name, message);
    let triangles = object.triangles.as_slice();
    let tet_count = object.triangle_tet_count.as_slice();
    let range = object.particles();
    let surface: Vec<bool> = (0..triangles.len())
        .map(|t| tet_count.get(t).copied().unwrap_or(0) < 2)
        .collect();
    for (t, &[a, b, c]) in triangles.iter().enumerate() {
        for v in [a, b, c] {
            if !range.contains(&(v as usize)) || v as usize >= particles {
                return Err(bad(format!(
                    "triangle {t} ({a}, {b}, {c}) is outside the object's particles {}..{} \
                     (the scene has {particles})",
                    range.start, range.end
                )));
            }
        }
        if a == b || b == c || c == a {
            return Err(bad(format!(
                "triangle {t} ({a}, {b}, {c}) repeats a vertex"
            )));
        }
    }
    if !object.is_manifold() {
        return Err(bad(
            "the surface is not manifold (an edge is shared by more than two triangles): \
             pressure needs an inside and an outside"
                .into(),
        ));
    }

    // Adjacency over surface triangles: (neighbour, whether it must be flipped relative).
    let pairs: Vec<TrianglePair> = object
        .triangle_pairs
        .iter()
        .copied()
        .filter(|p| {
            p.triangles
                .iter()
                .all(|&t| surface.get(t as usize).copied().unwrap_or(false))
        })
        .collect();
    let mut neighbours: Vec<Vec<(u32, bool)>> = vec![Vec::new(); triangles.len()];
    for p in &pairs {
        let [t1, t2] = p.triangles;
        let [i, j] = p.edge;
        if !traverses(triangles[t1 as usize], i, j) {
            return Err(bad(format!(
                "triangle pair ({t1}, {t2}): the shared edge ({i}, {j}) is not traversed by \
                 triangle {t1}"
            )));
        }
        // Two consistently oriented neighbours traverse their shared edge in opposite
        // directions: if t2 also goes i → j, one of them must be flipped.
        let flip = traverses(triangles[t2 as usize], i, j);
        neighbours[t1 as usize].push((t2, flip));
        neighbours[t2 as usize].push((t1, flip));
    }

    // Breadth-first search: component and flip of every surface triangle.
    let mut component = vec![u32::MAX; triangles.len()];
    let mut flipped = vec![false; triangles.len()];
    let mut components: Vec<Vec<u32>> = Vec::new();
    let mut queue = VecDeque::new();
    for seed in 0..triangles.len() {
        if !surface[seed] || component[seed] != u32::MAX {
            continue;
        }
        let id = components.len() as u32;
        let mut members = vec![seed as u32];
        component[seed] = id;
        queue.push_back(seed as u32);
        while let Some(t) = queue.pop_front() {
            for &(n, flip) in &neighbours[t as usize] {
                let want = flipped[t as usize] ^ flip;
                if component[n as usize] == u32::MAX {
                    component[n as usize] = id;
                    flipped[n as usize] = want;
                    members.push(n);
                    queue.push_back(n);
                } else if flipped[n as usize] != want {
                    return Err(bad(format!(
                        "the surface is not orientable (like a Möbius strip): triangles {t} \
                         and {n} cannot be wound consistently, so it has no inside"
                    )));
                }
            }
        }
        members.sort_unstable();
        components.push(members);
    }

    // Directed boundary edges per component, from the complex's boundary edges.
    let mut owner: BTreeMap<[u32; 2], Vec<(u32, [u32; 2])>> = BTreeMap::new();
    let wound = |t: usize| {
        let [a, b, c] = triangles[t];
        if flipped[t] {
            [a, c, b]
        } else {
            [a, b, c]
        }
    };
    for t in (0..triangles.len()).filter(|&t| surface[t]) {
        for [i, j] in directed_edges(wound(t)) {
            owner
                .entry([i.min(j), i.max(j)])
                .or_default()
                .push((t as u32, [i, j]));
        }
    }
    let mut boundary: Vec<Vec<[u32; 2]>> = vec![Vec::new(); components.len()];
    for &[a, b] in object.boundary_edges.as_slice() {
        let key = [a.min(b), a.max(b)];
        match owner.get(&key).map(Vec::as_slice) {
            Some(&[(t, directed)]) => boundary[component[t as usize] as usize].push(directed),
            _ => {
                return Err(bad(format!(
                    "boundary edge ({a}, {b}) is not in exactly one surface triangle"
                )))
            }
        }
    }
    let in_one = owner.values().filter(|v| v.len() == 1).count();
    if in_one != object.boundary_edges.len() {
        return Err(bad(format!(
            "the scene lists {} boundary edges but {in_one} surface edges are in exactly one \
             triangle",
            object.boundary_edges.len()
        )));
    }

    components
        .iter()
        .zip(boundary)
        .map(|(members, edges)| {
            let mut vertices: Vec<u32> = members
                .iter()
                .flat_map(|&t| triangles[t as usize])
                .collect();
            vertices.sort_unstable();
            vertices.dedup();
            let local = |v: u32| vertices.binary_search(&v).map(|l| l as u32);
            let local = |v: u32| local(v).map_err(|_| bad(format!("vertex {v} lost")));
            let tris = members
                .iter()
                .map(|&t| {
                    let [a, b, c] = wound(t as usize);
                    Ok([local(a)?, local(b)?, local(c)?])
                })
                .collect::<Result<Vec<_>, PluginError>>()?;
            let loops = chain_loops(edges)
                .map_err(|v| {
                    bad(format!(
                        "the boundary does not close into loops at vertex {v}"
                    ))
                })?
                .into_iter()
                .map(|ring| ring.into_iter().map(local).collect())
                .collect::<Result<Vec<Vec<u32>>, PluginError>>()?;
            Ok(Chamber {
                vertices,
                triangles: tris,
                loops,
            })
        })
        .collect()
}

/// Chains directed edges into closed loops (each a vertex sequence, the closing edge from
/// the last vertex back to the first implied). Deterministic: each loop starts at the smallest
/// unused edge and follows, at every vertex, its smallest unused outgoing edge. An edge set in
/// which some vertex has more edges in than out fails with that vertex.
pub fn chain_loops(mut edges: Vec<[u32; 2]>) -> Result<Vec<Vec<u32>>, u32> {
    edges.sort_unstable();
    let mut used = vec![false; edges.len()];
    let mut loops = Vec::new();
    for first in 0..edges.len() {
        if used[first] {
            continue;
        }
        used[first] = true;
        let [start, mut at] = edges[first];
        let mut ring = vec![start];
        while at != start {
            ring.push(at);
            let from = edges.partition_point(|e| e[0] < at);
            let next = (from..edges.len())
                .take_while(|&k| edges[k][0] == at)
                .find(|&k| !used[k])
                .ok_or(at)?;
            used[next] = true;
            at = edges[next][1];
        }
        loops.push(ring);
    }
    Ok(loops)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nucleus_sdk::abi_stable::std_types::RSlice;

    /// An object's topology as the core derives it, built here by hand.
    struct Topo {
        triangles: Vec<[u32; 3]>,
        pairs: Vec<TrianglePair>,
        boundary: Vec<[u32; 2]>,
        manifold: bool,
        count: u32,
    }

    impl Topo {
        /// Pairs and boundary edges derived as the core does (pairs per sorted edge, the
        /// edge ordered as the first triangle traverses it).
        fn new(count: u32, triangles: Vec<[u32; 3]>) -> Self {
            let mut by_edge: BTreeMap<[u32; 2], Vec<u32>> = BTreeMap::new();
            for (t, tri) in triangles.iter().enumerate() {
                for [i, j] in directed_edges(*tri) {
                    by_edge
                        .entry([i.min(j), i.max(j)])
                        .or_default()
                        .push(t as u32);
                }
            }
            let mut pairs = Vec::new();
            let mut boundary = Vec::new();
            let mut manifold = true;
            for (edge, ts) in &by_edge {
                manifold &= ts.len() <= 2;
                if ts.len() == 1 {
                    boundary.push(*edge);
                }
                for a in 0..ts.len() {
                    for b in a + 1..ts.len() {
                        let (t1, t2) = (ts[a], ts[b]);
                        let w = triangles[t1 as usize];
                        let [i, j] = if traverses(w, edge[0], edge[1]) {
                            *edge
                        } else {
                            [edge[1], edge[0]]
                        };
                        let third = |t: [u32; 3]| *t.iter().find(|&&v| v != i && v != j).unwrap();
                        pairs.push(TrianglePair {
                            triangles: [t1, t2],
                            edge: [i, j],
                            opposite: [third(w), third(triangles[t2 as usize])],
                        });
                    }
                }
            }
            Self {
                triangles,
                pairs,
                boundary,
                manifold,
                count,
            }
        }

        fn chambers(&self) -> Result<Vec<Chamber>, PluginError> {
            let view = ObjectView {
                triangles: RSlice::from_slice(&self.triangles),
                triangle_pairs: RSlice::from_slice(&self.pairs),
                boundary_edges: RSlice::from_slice(&self.boundary),
                closed: self.boundary.is_empty() as u8,
                manifold: self.manifold as u8,
                ..ObjectView::new("thing", 0, self.count)
            };
            chambers(&view, self.count as usize)
        }
    }

    /// Whether every interior edge of the chamber is traversed once each way.
    fn consistent(c: &Chamber) -> bool {
        let mut seen = std::collections::BTreeSet::new();
        c.triangles
            .iter()
            .flat_map(|t| directed_edges(*t))
            .all(|e| seen.insert(e))
    }

    /// A tetrahedron's four faces, with faces 1 and 3 wound the wrong way.
    fn scrambled_tetrahedron() -> Topo {
        Topo::new(4, vec![[0, 2, 1], [0, 3, 2], [0, 1, 3], [1, 3, 2]])
    }

    #[test]
    fn inconsistent_windings_are_made_consistent() {
        let c = scrambled_tetrahedron().chambers().expect("orientable");
        assert_eq!(c.len(), 1);
        assert!(c[0].is_closed());
        assert!(consistent(&c[0]), "{:?}", c[0].triangles);
        // The first triangle keeps its winding.
        assert_eq!(c[0].triangles[0], [0, 2, 1]);
    }

    #[test]
    fn disjoint_shells_are_separate_chambers() {
        let mut t = scrambled_tetrahedron().triangles;
        t.extend([[4, 5, 6], [4, 6, 7], [4, 7, 5], [5, 7, 6]]);
        let c = Topo::new(8, t).chambers().expect("orientable");
        assert_eq!(c.len(), 2);
        assert_eq!(c[1].vertices, [4, 5, 6, 7]);
        assert!(c.iter().all(|c| c.is_closed() && consistent(c)));
    }

    /// A strip of `n` quads around a loop; with `twist` the ends are glued after a half turn
    /// (a Möbius strip).
    fn strip(n: u32, twist: bool) -> Topo {
        let mut t = Vec::new();
        for k in 0..n {
            let (a, b) = (2 * k, 2 * k + 1);
            let (c, d) = if k + 1 < n {
                (2 * k + 2, 2 * k + 3)
            } else if twist {
                (1, 0)
            } else {
                (0, 1)
            };
            t.push([a, c, d]);
            t.push([a, d, b]);
        }
        Topo::new(2 * n, t)
    }

    #[test]
    fn a_moebius_strip_is_refused_naming_the_object() {
        let e = strip(6, true)
            .chambers()
            .expect_err("a Möbius strip has no inside");
        assert_eq!(e.code, PluginError::BAD_OBJECT);
        assert_eq!(e.subject.as_str(), "thing");
        assert!(e.message.contains("not orientable"), "{e}");
    }

    #[test]
    fn an_annulus_has_two_boundary_loops_running_opposite_ways() {
        let c = strip(6, false)
            .chambers()
            .expect("an annulus is orientable");
        let [c] = &c[..] else { panic!("one chamber") };
        assert!(!c.is_closed() && consistent(c));
        assert_eq!(c.loops.len(), 2);
        // Each loop follows its triangles' edges.
        let edges: std::collections::BTreeSet<[u32; 2]> = c
            .triangles
            .iter()
            .flat_map(|t| directed_edges(*t))
            .collect();
        for ring in &c.loops {
            assert_eq!(ring.len(), 6);
            for k in 0..ring.len() {
                let e = [ring[k], ring[(k + 1) % ring.len()]];
                assert!(edges.contains(&e), "{e:?} not traversed");
            }
        }
    }

    #[test]
    fn a_non_manifold_surface_is_refused() {
        // Three triangles on the edge (0, 1).
        let e = Topo::new(5, vec![[0, 1, 2], [1, 0, 3], [0, 1, 4]])
            .chambers()
            .expect_err("non-manifold");
        assert_eq!(e.subject.as_str(), "thing");
        assert!(e.message.contains("not manifold"), "{e}");
    }

    #[test]
    fn a_triangle_outside_the_object_is_refused() {
        let mut t = Topo::new(3, vec![[0, 1, 2]]);
        t.triangles[0] = [0, 1, 7];
        let e = t.chambers().expect_err("out of range");
        assert_eq!(e.code, PluginError::BAD_OBJECT);
    }

    #[test]
    fn boundary_edges_that_disagree_with_the_triangles_are_refused() {
        let mut t = Topo::new(3, vec![[0, 1, 2]]);
        t.boundary.pop();
        assert!(t.chambers().is_err());
    }

    #[test]
    fn flipping_reverses_triangles_and_loops() {
        let mut c = strip(4, false).chambers().expect("annulus").remove(0);
        let before = c.clone();
        c.flip();
        assert!(consistent(&c));
        assert_ne!(c, before);
        c.flip();
        assert_eq!(c, before);
    }

    #[test]
    fn loops_chain_deterministically_and_report_dangling_vertices() {
        let loops = chain_loops(vec![[5, 3], [3, 9], [9, 5], [1, 2], [2, 1]]).expect("closed");
        assert_eq!(loops, vec![vec![1, 2], vec![3, 9, 5]]);
        assert_eq!(chain_loops(vec![[1, 2], [2, 3]]), Err(3));
    }
}
