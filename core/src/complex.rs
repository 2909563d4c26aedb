//! The simplicial complex: the topology of one object, the paper's single `simplex` record.
//!
//! All matter is a simplicial complex of points (0-simplices), edges (1), triangles (2) and
//! tetrahedra (3), glued freely. Each [`Simplex`] stores what the paper's record stores: its
//! dimension `k`, an orientation sign, its `k + 1` vertex indices sorted ascending, its `k + 1`
//! faces of dimension `k − 1` (children) and the simplices of dimension `k + 1` it is a face
//! of (parents).
//!
//! This module is pure topology: integers only, no positions. Vertex indices are local to
//! one object (`0..n_vertices`).
//!
//! # Contract of [`Complex::build`]
//!
//! * Every vertex `0..n_vertices` is a 0-simplex whose index is the vertex id.
//! * A simplex given twice (the same vertex set) is stored once, with its first orientation.
//! * Faces are derived and shared: a tet's four triangles and six edges, a triangle's three
//!   edges. Each simplex is stored once however many simplices it is a face of.
//! * List order, per dimension: the given simplices first, in the given order (less
//!   repeats), then the derived ones in the order their first parent lists them. So when
//!   nothing is repeated, a given simplex's index is its position in the input.
//! * `faces[i]` is the face opposite `vertices[i]` (the face without that vertex), as in the
//!   boundary operator `∂[v0..vk] = Σ (−1)^i [v0..v̂i..vk]`. `parents` is sorted ascending.
//! * Orientation ([`Simplex::sign`]): for a given simplex, the parity of the permutation
//!   that sorts its vertices as given (+1 even, −1 odd), so the given winding can be
//!   rebuilt from the sorted vertices and the sign. A triangle derived from a tet (and not
//!   given) takes the orientation the boundary of its **first** parent tet induces on it:
//!   `∂[v0,v1,v2,v3] = +[v1,v2,v3] − [v0,v2,v3] + [v0,v1,v3] − [v0,v1,v2]`, times that tet's
//!   sign. For a tet whose given order is geometrically positive
//!   (`det(v1 − v0, v2 − v0, v3 − v0) > 0`) its faces then wind outward, so a tet-derived
//!   triangle's sign is ±1, never 0. Derived edges and vertices that are not given have
//!   sign 0 (unoriented); a given point has sign +1.
//! * Errors ([`ComplexError`]): a vertex index out of range or a vertex repeated within one
//!   simplex (`[3, 3]`, `[1, 1, 2]`), naming the list and the element. A triangle whose
//!   distinct vertices happen to be collinear is geometry, not topology, and is accepted.
//!
//! Every query returns its data in a deterministic order (list order or sorted): building
//! the same input twice gives identical results.

use std::collections::HashMap;

/// "No such vertex or face": fills the unused slots of [`Simplex::vertices`] and
/// [`Simplex::faces`].
pub const NONE: u32 = u32::MAX;

/// One k-simplex: the paper's `simplex` record.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Simplex {
    /// `k`: 0 point, 1 edge, 2 triangle, 3 tet.
    pub dim: u8,
    /// +1/−1: the parity of the permutation that sorts the vertices as given (for a
    /// tet-derived triangle: the orientation its first tet induces on it). 0 where
    /// unoriented: a face only derived from a higher simplex, never given.
    pub sign: i8,
    /// Sorted ascending; only the first `dim + 1` are meaningful, the rest are [`NONE`].
    pub vertices: [u32; 4],
    /// Indices (into the `dim − 1` list) of its `dim + 1` faces; `faces[i]` is the face
    /// opposite `vertices[i]`. Only the first `dim + 1` are meaningful; all [`NONE`] for
    /// `dim == 0`.
    pub faces: [u32; 4],
    /// Indices (into the `dim + 1` list) of the simplices it is a face of, ascending.
    pub parents: Vec<u32>,
}

impl Simplex {
    /// The meaningful (first `dim + 1`) sorted vertices.
    pub fn vertex_slice(&self) -> &[u32] {
        &self.vertices[..=usize::from(self.dim)]
    }
}

/// Two triangles sharing an edge, in object-local indices.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TrianglePairLocal {
    /// The two triangles (indices into the triangle list), first < second.
    pub triangles: [u32; 2],
    /// The shared edge `(i, j)`, ordered as the first triangle's winding traverses it.
    pub edge: [u32; 2],
    /// The third vertex of the first triangle, then of the second.
    pub opposite: [u32; 2],
}

/// Why a complex cannot be built.
#[derive(thiserror::Error, Debug, PartialEq)]
pub enum ComplexError {
    /// A simplex refers to a vertex that does not exist.
    #[error(
        "{list}[{element}] refers to vertex {vertex}, but the object has {n_vertices} vertices"
    )]
    VertexOutOfRange {
        /// `"points"`, `"edges"`, `"triangles"` or `"tets"`.
        list: &'static str,
        /// Position of the simplex in that list.
        element: usize,
        /// The offending vertex index.
        vertex: u32,
        /// The number of vertices of the object.
        n_vertices: usize,
    },
    /// A simplex names the same vertex twice: it is degenerate.
    #[error("{list}[{element}] = {vertices:?} repeats vertex {vertex} (a degenerate simplex)")]
    RepeatedVertex {
        /// `"edges"`, `"triangles"` or `"tets"`.
        list: &'static str,
        /// Position of the simplex in that list.
        element: usize,
        /// The simplex as given.
        vertices: Vec<u32>,
        /// The repeated vertex.
        vertex: u32,
    },
    /// More simplices of one dimension than `u32` indices can address.
    #[error("too many {dim}-simplices ({count}) for u32 indices")]
    TooMany {
        /// The dimension.
        dim: u8,
        /// How many there would be.
        count: usize,
    },
}

/// A simplicial complex: simplices by dimension (0..=3) over `n_vertices` vertices.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Complex {
    n_vertices: usize,
    simplices: [Vec<Simplex>; 4],
}

/// The simplices of one dimension while building, with their index by vertex set.
struct Level {
    dim: u8,
    list: Vec<Simplex>,
    index: HashMap<[u32; 4], u32>,
}

impl Level {
    fn new(dim: u8) -> Self {
        Level {
            dim,
            list: Vec::new(),
            index: HashMap::new(),
        }
    }

    /// The index of the simplex with these sorted vertices, inserted with `sign` if new.
    fn insert(&mut self, sorted: &[u32], sign: i8) -> Result<u32, ComplexError> {
        let mut key = [NONE; 4];
        key[..sorted.len()].copy_from_slice(sorted);
        if let Some(&i) = self.index.get(&key) {
            return Ok(i);
        }
        let i = index_of(self.list.len(), self.dim)?;
        self.list.push(Simplex {
            dim: self.dim,
            sign,
            vertices: key,
            faces: [NONE; 4],
            parents: Vec::new(),
        });
        self.index.insert(key, i);
        Ok(i)
    }

    /// Derives the faces of every simplex of `self` into `lower` (one dimension down), filling
    /// `faces` and `parents`. `face_sign(parent_sign, i)` orients a new face opposite vertex i.
    fn derive_faces(
        &mut self,
        lower: &mut Level,
        face_sign: impl Fn(i8, usize) -> i8,
    ) -> Result<(), ComplexError> {
        for (s, simplex) in self.list.iter_mut().enumerate() {
            let vertices = simplex.vertex_slice().to_vec();
            for i in 0..vertices.len() {
                let mut face = vertices.clone();
                face.remove(i);
                let f = lower.insert(&face, face_sign(simplex.sign, i))?;
                simplex.faces[i] = f;
                // `s` fits u32: it was checked when the simplex was inserted.
                lower.list[f as usize].parents.push(s as u32);
            }
        }
        Ok(())
    }
}

/// `len` as the index of the next simplex of dimension `dim`.
fn index_of(len: usize, dim: u8) -> Result<u32, ComplexError> {
    u32::try_from(len)
        .ok()
        .filter(|&i| i != NONE)
        .ok_or(ComplexError::TooMany { dim, count: len })
}

/// Checks one given simplex and returns its sorted vertices and orientation sign.
fn checked<const N: usize>(
    list: &'static str,
    element: usize,
    given: [u32; N],
    n_vertices: usize,
) -> Result<([u32; N], i8), ComplexError> {
    if let Some(&vertex) = given.iter().find(|&&v| v as usize >= n_vertices) {
        return Err(ComplexError::VertexOutOfRange {
            list,
            element,
            vertex,
            n_vertices,
        });
    }
    let mut sorted = given;
    sorted.sort_unstable();
    if let Some(w) = sorted.windows(2).find(|w| w[0] == w[1]) {
        return Err(ComplexError::RepeatedVertex {
            list,
            element,
            vertices: given.to_vec(),
            vertex: w[0],
        });
    }
    Ok((sorted, parity(&given)))
}

/// +1 if sorting `v` (distinct values) takes an even permutation, −1 if odd.
fn parity(v: &[u32]) -> i8 {
    let inversions = (0..v.len())
        .flat_map(|a| (a + 1..v.len()).map(move |b| (a, b)))
        .filter(|&(a, b)| v[a] > v[b])
        .count();
    if inversions % 2 == 0 {
        1
    } else {
        -1
    }
}

impl Complex {
    /// Builds the complex of an object with `n_vertices` vertices from its given simplices,
    /// deriving and sharing all faces (see the module doc for the contract).
    pub fn build(
        n_vertices: usize,
        points: &[u32],
        edges: &[[u32; 2]],
        triangles: &[[u32; 3]],
        tets: &[[u32; 4]],
    ) -> Result<Complex, ComplexError> {
        if n_vertices > NONE as usize {
            return Err(ComplexError::TooMany {
                dim: 0,
                count: n_vertices,
            });
        }
        fn check_all<const N: usize>(
            list: &'static str,
            given: &[[u32; N]],
            n: usize,
        ) -> Result<Vec<([u32; N], i8)>, ComplexError> {
            given
                .iter()
                .enumerate()
                .map(|(e, &s)| checked(list, e, s, n))
                .collect()
        }
        let points = check_all(
            "points",
            &points.iter().map(|&p| [p]).collect::<Vec<_>>(),
            n_vertices,
        )?;
        let edges = check_all("edges", edges, n_vertices)?;
        let triangles = check_all("triangles", triangles, n_vertices)?;
        let tets = check_all("tets", tets, n_vertices)?;

        let mut level3 = Level::new(3);
        for (t, sign) in &tets {
            level3.insert(t, *sign)?;
        }
        let mut level2 = Level::new(2);
        for (t, sign) in &triangles {
            level2.insert(t, *sign)?;
        }
        // The induced boundary orientation: face i of the tet carries (−1)^i.
        level3.derive_faces(&mut level2, |sign, i| if i % 2 == 0 { sign } else { -sign })?;
        let mut level1 = Level::new(1);
        for (e, sign) in &edges {
            level1.insert(e, *sign)?;
        }
        level2.derive_faces(&mut level1, |_, _| 0)?;
        let mut level0 = Level::new(0);
        for v in 0..n_vertices as u32 {
            level0.insert(&[v], 0)?;
        }
        for ([p], _) in &points {
            level0.list[*p as usize].sign = 1;
        }
        level1.derive_faces(&mut level0, |_, _| 0)?;

        Ok(Complex {
            n_vertices,
            simplices: [level0.list, level1.list, level2.list, level3.list],
        })
    }

    /// The number of vertices (0-simplices).
    pub fn n_vertices(&self) -> usize {
        self.n_vertices
    }

    /// The simplices of dimension `dim` (empty above 3).
    pub fn simplices(&self, dim: usize) -> &[Simplex] {
        self.simplices.get(dim).map_or(&[], Vec::as_slice)
    }

    /// The number of simplices of dimension `dim` (0 above 3).
    pub fn count(&self, dim: usize) -> usize {
        self.simplices(dim).len()
    }

    /// The number of parents of simplex `index` of dimension `dim` (for a vertex: the number
    /// of edges at it); 0 if there is no such simplex.
    pub fn valence(&self, dim: usize, index: usize) -> usize {
        self.simplices(dim)
            .get(index)
            .map_or(0, |s| s.parents.len())
    }

    /// Every edge as `[lo, hi]`, in edge list order.
    pub fn edges(&self) -> Vec<[u32; 2]> {
        self.simplices(1)
            .iter()
            .map(|e| [e.vertices[0], e.vertices[1]])
            .collect()
    }

    /// Per edge, the number of triangles containing it (0: a curve edge, 1: a boundary edge,
    /// 2: an interior edge of a manifold surface).
    pub fn edge_triangle_count(&self) -> Vec<u32> {
        self.simplices(1)
            .iter()
            .map(|e| e.parents.len() as u32)
            .collect()
    }

    /// Every triangle in its oriented winding: the sorted vertices for sign +1 (and 0), the
    /// sorted vertices with the last two swapped for −1. A given triangle comes back as a
    /// cyclic rotation of the given one; a tet-derived one winds outward from its first tet.
    pub fn triangles_oriented(&self) -> Vec<[u32; 3]> {
        self.simplices(2).iter().map(oriented_triangle).collect()
    }

    /// Every tet, as an even permutation of the given order (the same orientation).
    pub fn tets(&self) -> Vec<[u32; 4]> {
        self.simplices(3)
            .iter()
            .map(|t| {
                let [a, b, c, d] = t.vertices;
                if t.sign < 0 {
                    [a, b, d, c]
                } else {
                    [a, b, c, d]
                }
            })
            .collect()
    }

    /// For every edge (in edge order) in two or more triangles, every pair of those triangles
    /// `t1 < t2`, with the edge ordered as `t1`'s winding traverses it.
    pub fn triangle_pairs(&self) -> Vec<TrianglePairLocal> {
        let triangles = self.simplices(2);
        let mut pairs = Vec::new();
        for edge in self.simplices(1) {
            for (a, &t1) in edge.parents.iter().enumerate() {
                for &t2 in &edge.parents[a + 1..] {
                    let w = oriented_triangle(&triangles[t1 as usize]);
                    let [i, j] = edge_in_winding(w, [edge.vertices[0], edge.vertices[1]]);
                    pairs.push(TrianglePairLocal {
                        triangles: [t1, t2],
                        edge: [i, j],
                        opposite: [
                            third_vertex(&triangles[t1 as usize], edge),
                            third_vertex(&triangles[t2 as usize], edge),
                        ],
                    });
                }
            }
        }
        pairs
    }

    /// For every vertex `j` (ascending), every pair of curve edges (edges in no triangle)
    /// meeting at `j`, as `[i, j, k]` with `i < k`, pairs in lexicographic order.
    pub fn edge_pairs(&self) -> Vec<[u32; 3]> {
        let edges = self.simplices(1);
        let mut pairs = Vec::new();
        for vertex in self.simplices(0) {
            let j = vertex.vertices[0];
            let mut others: Vec<u32> = vertex
                .parents
                .iter()
                .map(|&e| &edges[e as usize])
                .filter(|e| e.parents.is_empty())
                .map(|e| other_end(e, j))
                .collect();
            others.sort_unstable();
            for (a, &i) in others.iter().enumerate() {
                for &k in &others[a + 1..] {
                    pairs.push([i, j, k]);
                }
            }
        }
        pairs
    }

    /// Indices of the `dim`-simplices with exactly one parent: curve end points (0), boundary
    /// edges of a surface (1), boundary triangles of a tet solid (2). Empty for 3 and above.
    pub fn boundary(&self, dim: usize) -> Vec<u32> {
        (0u32..)
            .zip(self.simplices(dim))
            .filter(|(_, s)| s.parents.len() == 1)
            .map(|(i, _)| i)
            .collect()
    }

    /// The boundary edges (in exactly one triangle) as `[lo, hi]`, in edge list order.
    pub fn boundary_edges(&self) -> Vec<[u32; 2]> {
        let edges = self.simplices(1);
        self.boundary(1)
            .into_iter()
            .map(|e| {
                let v = edges[e as usize].vertices;
                [v[0], v[1]]
            })
            .collect()
    }

    /// Whether the surface is closed: the complex has triangles and every edge that is in
    /// any triangle is in at least two (no boundary edge). Curve edges do not matter. A tet
    /// solid is closed through its tets' faces.
    pub fn is_closed(&self) -> bool {
        self.count(2) > 0 && self.simplices(1).iter().all(|e| e.parents.len() != 1)
    }

    /// Whether every surface triangle's edge is in at most two surface triangles, and every
    /// triangle in at most two tets. A *surface* triangle is one not inside a solid (fewer than
    /// two parent tets): the given triangles of a shell and the boundary faces of a tet solid.
    /// (Counting every triangle would call two tets sharing a face non-manifold: the edges
    /// of the shared face are in three triangles.)
    pub fn is_manifold(&self) -> bool {
        self.simplices(2).iter().all(|t| t.parents.len() <= 2)
            && self
                .simplices(1)
                .iter()
                .all(|e| self.surface_parents(e).count() <= 2)
    }

    /// Whether the surface is consistently oriented: it is manifold ([`Self::is_manifold`])
    /// and every edge shared by two surface triangles is traversed in opposite directions by
    /// them. True for a closed tet solid's outward faces, and for a surface without triangles.
    pub fn orientation_consistent(&self) -> bool {
        let triangles = self.simplices(2);
        self.is_manifold()
            && self.simplices(1).iter().all(|e| {
                let shared: Vec<u32> = self.surface_parents(e).collect();
                let [t1, t2] = shared[..] else {
                    return true;
                };
                let edge = [e.vertices[0], e.vertices[1]];
                let d1 = edge_in_winding(oriented_triangle(&triangles[t1 as usize]), edge);
                let d2 = edge_in_winding(oriented_triangle(&triangles[t2 as usize]), edge);
                d1 != d2
            })
    }

    /// Vertices with no edge (hence no triangle or tet) at them, ascending.
    pub fn isolated_points(&self) -> Vec<u32> {
        (0u32..)
            .zip(self.simplices(0))
            .filter(|(_, v)| v.parents.is_empty())
            .map(|(i, _)| i)
            .collect()
    }

    /// The parent triangles of an edge that are surface triangles (fewer than two tets).
    fn surface_parents<'a>(&'a self, edge: &'a Simplex) -> impl Iterator<Item = u32> + 'a {
        let triangles = self.simplices(2);
        edge.parents
            .iter()
            .copied()
            .filter(move |&t| triangles[t as usize].parents.len() < 2)
    }
}

/// The triangle in its oriented winding (sign −1 swaps the last two sorted vertices).
fn oriented_triangle(t: &Simplex) -> [u32; 3] {
    let [a, b, c, _] = t.vertices;
    if t.sign < 0 {
        [a, c, b]
    } else {
        [a, b, c]
    }
}

/// The edge `{p, q}` ordered as the winding `w` traverses it.
fn edge_in_winding(w: [u32; 3], [p, q]: [u32; 2]) -> [u32; 2] {
    let forward = (0..3).any(|i| w[i] == p && w[(i + 1) % 3] == q);
    if forward {
        [p, q]
    } else {
        [q, p]
    }
}

/// The vertex of triangle `t` that is not on `edge`.
fn third_vertex(t: &Simplex, edge: &Simplex) -> u32 {
    let on_edge = &edge.vertices[..2];
    t.vertices[..3]
        .iter()
        .copied()
        .find(|v| !on_edge.contains(v))
        .unwrap_or(NONE)
}

/// The end of `edge` that is not `v`.
fn other_end(edge: &Simplex, v: u32) -> u32 {
    if edge.vertices[0] == v {
        edge.vertices[1]
    } else {
        edge.vertices[0]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    fn surface(n: usize, triangles: &[[u32; 3]]) -> Complex {
        Complex::build(n, &[], &[], triangles, &[]).unwrap()
    }

    fn solid(n: usize, tets: &[[u32; 4]]) -> Complex {
        Complex::build(n, &[], &[], &[], tets).unwrap()
    }

    fn curve(n: usize, edges: &[[u32; 2]]) -> Complex {
        Complex::build(n, &[], edges, &[], &[]).unwrap()
    }

    /// All orderings of `v`.
    fn permutations<const N: usize>(v: [u32; N]) -> Vec<[u32; N]> {
        fn all(v: &[u32]) -> Vec<Vec<u32>> {
            if v.len() <= 1 {
                return vec![v.to_vec()];
            }
            (0..v.len())
                .flat_map(|i| {
                    let mut rest = v.to_vec();
                    let first = rest.remove(i);
                    all(&rest).into_iter().map(move |mut p| {
                        p.insert(0, first);
                        p
                    })
                })
                .collect()
        }
        all(&v).into_iter().map(|p| p.try_into().unwrap()).collect()
    }

    fn is_cyclic_rotation(a: [u32; 3], b: [u32; 3]) -> bool {
        (0..3).any(|r| (0..3).all(|i| a[i] == b[(i + r) % 3]))
    }

    fn det(p: &[DVec3], t: [u32; 4]) -> f64 {
        let [a, b, c, d] = t.map(|i| p[i as usize]);
        (b - a).cross(c - a).dot(d - a)
    }

    fn unit_tet_positions() -> Vec<DVec3> {
        vec![DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::Z, DVec3::ONE]
    }

    /// An n×n vertex grid, two consistently wound triangles per cell.
    fn grid(n: u32) -> Vec<[u32; 3]> {
        let mut triangles = Vec::new();
        for r in 0..n - 1 {
            for c in 0..n - 1 {
                let a = r * n + c;
                let (b, d, e) = (a + 1, a + n, a + n + 1);
                triangles.push([a, b, e]);
                triangles.push([a, e, d]);
            }
        }
        triangles
    }

    #[test]
    fn permutations_helper_lists_all() {
        assert_eq!(permutations([0, 1, 2]).len(), 6);
        assert_eq!(permutations([0, 1, 2, 3]).len(), 24);
    }

    #[test]
    fn triangle_sign_is_permutation_parity() {
        let expected = [
            ([0, 1, 2], 1),
            ([0, 2, 1], -1),
            ([1, 0, 2], -1),
            ([1, 2, 0], 1),
            ([2, 0, 1], 1),
            ([2, 1, 0], -1),
        ];
        for (given, sign) in expected {
            let c = surface(3, &[given]);
            assert_eq!(c.simplices(2)[0].sign, sign, "{given:?}");
            assert_eq!(c.simplices(2)[0].vertices, [0, 1, 2, NONE]);
        }
    }

    #[test]
    fn tet_sign_is_permutation_parity() {
        let expected = [
            ([0, 1, 2, 3], 1),
            ([1, 0, 2, 3], -1),
            ([1, 2, 0, 3], 1),
            ([1, 2, 3, 0], -1),
            ([1, 0, 3, 2], 1),
            ([3, 2, 1, 0], 1),
            ([0, 1, 3, 2], -1),
        ];
        for (given, sign) in expected {
            assert_eq!(solid(4, &[given]).simplices(3)[0].sign, sign, "{given:?}");
        }
    }

    #[test]
    fn edge_sign_follows_given_direction() {
        let c = curve(2, &[[1, 0]]);
        assert_eq!(c.simplices(1)[0].sign, -1);
        assert_eq!(c.edges(), [[0, 1]]);
        assert_eq!(curve(2, &[[0, 1]]).simplices(1)[0].sign, 1);
    }

    #[test]
    fn derived_faces_are_unoriented_and_given_points_positive() {
        let c = Complex::build(4, &[3], &[], &[[0, 1, 2]], &[]).unwrap();
        assert!(c.simplices(1).iter().all(|e| e.sign == 0));
        let signs: Vec<i8> = c.simplices(0).iter().map(|v| v.sign).collect();
        assert_eq!(signs, [0, 0, 0, 1]);
    }

    #[test]
    fn given_triangle_keeps_its_winding() {
        for given in permutations([4, 7, 9]) {
            let c = surface(10, &[given]);
            let out = c.triangles_oriented()[0];
            assert!(
                is_cyclic_rotation(out, given),
                "{given:?} came back {out:?}"
            );
        }
    }

    #[test]
    fn given_tet_keeps_its_orientation() {
        let p = unit_tet_positions();
        for given in permutations([0, 1, 2, 3]) {
            let out = solid(4, &[given]).tets()[0];
            assert_eq!(det(&p, out).signum(), det(&p, given).signum(), "{given:?}");
        }
    }

    #[test]
    fn shared_edge_is_stored_once() {
        let c = surface(4, &[[0, 1, 2], [0, 2, 3]]);
        assert_eq!(c.count(0), 4);
        assert_eq!(c.count(1), 5);
        assert_eq!(c.count(2), 2);
        assert_eq!(c.edges(), [[1, 2], [0, 2], [0, 1], [2, 3], [0, 3]]);
        assert_eq!(c.edge_triangle_count(), [1, 2, 1, 1, 1]);
    }

    #[test]
    fn faces_are_opposite_vertices_and_parents_agree() {
        let c = surface(4, &[[0, 1, 2], [0, 2, 3]]);
        let [t0, t1] = [&c.simplices(2)[0], &c.simplices(2)[1]];
        assert_eq!(t0.faces, [0, 1, 2, NONE]);
        assert_eq!(t1.faces, [3, 4, 1, NONE]);
        // Every face lists its parent, and every parent its face.
        for dim in 1..=2 {
            for (s, simplex) in c.simplices(dim).iter().enumerate() {
                for (i, &f) in simplex.faces[..=dim].iter().enumerate() {
                    let face = &c.simplices(dim - 1)[f as usize];
                    assert!(face.parents.contains(&(s as u32)));
                    assert!(!face.vertex_slice().contains(&simplex.vertices[i]));
                }
            }
        }
        assert_eq!(c.simplices(1)[1].parents, [0, 1]);
        assert_eq!(c.simplices(1)[0].faces, [2, 1, NONE, NONE]);
        assert_eq!(c.simplices(0)[0].faces, [NONE; 4]);
        assert!(c.simplices(2).iter().all(|t| t.parents.is_empty()));
    }

    #[test]
    fn vertex_valence_counts_edges() {
        let c = surface(4, &[[0, 1, 2], [0, 2, 3]]);
        let valences: Vec<usize> = (0..4).map(|v| c.valence(0, v)).collect();
        assert_eq!(valences, [3, 2, 3, 2]);
        assert_eq!(c.valence(1, 1), 2);
        assert_eq!(c.valence(1, 99), 0);
        assert_eq!(c.valence(7, 0), 0);
    }

    #[test]
    fn repeated_simplex_is_stored_once_with_first_orientation() {
        let c = Complex::build(3, &[], &[[1, 0], [0, 1]], &[[0, 1, 2], [2, 1, 0]], &[]).unwrap();
        assert_eq!(c.count(2), 1);
        assert_eq!(c.simplices(2)[0].sign, 1);
        assert_eq!(c.count(1), 3);
        assert_eq!(c.simplices(1)[0].sign, -1);
    }

    #[test]
    fn given_simplices_come_first_in_given_order() {
        let c = Complex::build(4, &[], &[[2, 3], [0, 1]], &[[1, 2, 3]], &[]).unwrap();
        assert_eq!(c.edges(), [[2, 3], [0, 1], [1, 3], [1, 2]]);
        assert_eq!(c.simplices(1)[0].parents, [0]);
    }

    #[test]
    fn single_tet_has_four_triangles_and_six_edges() {
        let c = solid(4, &[[0, 1, 2, 3]]);
        assert_eq!(
            [c.count(0), c.count(1), c.count(2), c.count(3)],
            [4, 6, 4, 1]
        );
        assert!(c.edge_triangle_count().iter().all(|&n| n == 2));
        assert!(c.is_closed());
        assert!(c.is_manifold());
        assert!(c.orientation_consistent());
        assert_eq!(c.boundary(2), [0, 1, 2, 3]);
        assert!(c.boundary(1).is_empty());
        assert!(c.boundary(3).is_empty());
        assert_eq!(c.simplices(3)[0].faces, [0, 1, 2, 3]);
        assert!(c.simplices(2).iter().all(|t| t.sign != 0));
        assert_eq!(c.triangle_pairs().len(), 6);
    }

    #[test]
    fn tet_faces_wind_outward() {
        let p = unit_tet_positions();
        for given in permutations([0, 1, 2, 3]) {
            if det(&p, given) < 0.0 {
                continue;
            }
            let c = solid(4, &[given]);
            let center = (p[0] + p[1] + p[2] + p[3]) / 4.0;
            for t in c.triangles_oriented() {
                let [a, b, d] = t.map(|i| p[i as usize]);
                let normal = (b - a).cross(d - a);
                let out = (a + b + d) / 3.0 - center;
                assert!(
                    normal.dot(out) > 0.0,
                    "tet {given:?}: face {t:?} winds inward"
                );
            }
        }
    }

    #[test]
    fn given_triangle_orientation_wins_over_tet_face() {
        // The tet induces −[0,1,2] on its face opposite vertex 3; the given +[0,1,2] wins.
        let c = Complex::build(4, &[], &[], &[[0, 1, 2]], &[[0, 1, 2, 3]]).unwrap();
        assert_eq!(c.count(2), 4);
        assert_eq!(c.triangles_oriented()[0], [0, 1, 2]);
        assert_eq!(solid(4, &[[0, 1, 2, 3]]).triangles_oriented()[3], [0, 2, 1]);
    }

    #[test]
    fn two_tets_sharing_a_face_make_a_closed_consistent_solid() {
        let p = unit_tet_positions();
        let tets = [[0, 1, 2, 3], [1, 2, 3, 4]];
        assert!(tets.iter().all(|&t| det(&p, t) > 0.0));
        let c = solid(5, &tets);
        assert_eq!(c.count(2), 7);
        assert_eq!(c.count(1), 9);
        let shared = c
            .simplices(2)
            .iter()
            .position(|t| t.vertex_slice() == [1, 2, 3])
            .unwrap();
        assert_eq!(c.simplices(2)[shared].parents, [0, 1]);
        assert_eq!(c.boundary(2).len(), 6);
        assert!(!c.boundary(2).contains(&(shared as u32)));
        assert!(c.is_closed());
        assert!(c.is_manifold());
        assert!(c.orientation_consistent());
    }

    #[test]
    fn octahedron_surface_is_closed_manifold_and_consistent() {
        let p = [
            DVec3::X,
            -DVec3::X,
            DVec3::Y,
            -DVec3::Y,
            DVec3::Z,
            -DVec3::Z,
        ];
        let mut triangles = Vec::new();
        for x in [0, 1] {
            for y in [2, 3] {
                for z in [4, 5] {
                    let [a, b, c] = [x, y, z].map(|i| p[i as usize]);
                    let outward = (b - a).cross(c - a).dot(a + b + c) > 0.0;
                    triangles.push(if outward { [x, y, z] } else { [x, z, y] });
                }
            }
        }
        let c = surface(6, &triangles);
        assert_eq!([c.count(1), c.count(2)], [12, 8]);
        assert!(c.is_closed());
        assert!(c.is_manifold());
        assert!(c.orientation_consistent());
        assert!(c.boundary_edges().is_empty());
        assert_eq!(c.triangle_pairs().len(), 12);
        assert!((0..6).all(|v| c.valence(0, v) == 4));
    }

    #[test]
    fn tetrahedron_surface_is_closed() {
        let c = surface(4, &[[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]]);
        assert!(c.is_closed());
        assert!(c.orientation_consistent());
    }

    #[test]
    fn open_grid_has_4n_minus_4_boundary_edges() {
        for n in 2..6 {
            let c = surface((n * n) as usize, &grid(n));
            assert_eq!(c.boundary_edges().len() as u32, 4 * (n - 1), "n = {n}");
            assert_eq!(c.boundary(1).len() as u32, 4 * (n - 1));
            assert!(!c.is_closed());
            assert!(c.is_manifold());
            assert!(c.orientation_consistent());
        }
        let c = surface(9, &grid(3));
        assert!(c.boundary_edges().contains(&[0, 1]));
        assert!(!c.boundary_edges().contains(&[0, 4]));
    }

    #[test]
    fn triangle_pair_edge_follows_first_winding() {
        // [0,1,2] traverses the shared edge 2 → 0; [0,2,3] traverses it 0 → 2.
        let c = surface(4, &[[0, 1, 2], [0, 2, 3]]);
        assert_eq!(
            c.triangle_pairs(),
            [TrianglePairLocal {
                triangles: [0, 1],
                edge: [2, 0],
                opposite: [1, 3],
            }]
        );
        // The same quad given with the other winding reverses the edge.
        let c = surface(4, &[[2, 1, 0], [3, 2, 0]]);
        assert_eq!(c.triangle_pairs()[0].edge, [0, 2]);
        assert_eq!(c.triangle_pairs()[0].opposite, [1, 3]);
    }

    #[test]
    fn flipped_triangle_breaks_orientation_consistency() {
        let c = surface(4, &[[0, 1, 2], [0, 3, 2]]);
        assert!(c.is_manifold());
        assert!(!c.orientation_consistent());
    }

    #[test]
    fn three_triangles_on_an_edge_are_not_manifold() {
        let c = surface(5, &[[0, 1, 2], [1, 0, 3], [0, 1, 4]]);
        assert_eq!(c.edge_triangle_count()[2], 3);
        assert!(!c.is_manifold());
        assert!(!c.orientation_consistent());
        let on_shared: Vec<[u32; 2]> = c
            .triangle_pairs()
            .iter()
            .filter(|p| p.edge == [0, 1] || p.edge == [1, 0])
            .map(|p| p.triangles)
            .collect();
        assert_eq!(on_shared, [[0, 1], [0, 2], [1, 2]]);
    }

    #[test]
    fn mixed_complex_separates_curves_surfaces_and_points() {
        // A triangle, a dangling two-edge curve at vertex 2, and an isolated point 5.
        let c = Complex::build(6, &[5], &[[2, 3], [3, 4]], &[[0, 1, 2]], &[]).unwrap();
        assert_eq!(c.edge_triangle_count(), [0, 0, 1, 1, 1]);
        assert_eq!(c.isolated_points(), [5]);
        assert_eq!(c.edge_pairs(), [[2, 3, 4]]);
        assert_eq!(c.boundary(0), [4]);
        assert_eq!(c.boundary_edges().len(), 3);
        assert!(!c.is_closed());
        assert!(c.is_manifold());
        // Valences: vertex 2 joins the triangle's two edges and the curve's first one.
        let valences: Vec<usize> = (0..6).map(|v| c.valence(0, v)).collect();
        assert_eq!(valences, [2, 2, 3, 2, 1, 0]);
        // Children and parents across the dimensions: the triangle's faces are its three
        // edges, each of which has the triangle as its only parent; the curve's edges have none.
        let edge = |a: u32, b: u32| {
            c.simplices(1)
                .iter()
                .position(|e| e.vertex_slice() == [a, b])
                .expect("edge") as u32
        };
        let tri = &c.simplices(2)[0];
        let mut faces: Vec<u32> = tri.faces[..3].to_vec();
        faces.sort_unstable();
        let mut expected = vec![edge(0, 1), edge(0, 2), edge(1, 2)];
        expected.sort_unstable();
        assert_eq!(faces, expected);
        // faces[i] is opposite vertices[i]: the face opposite vertex 0 is edge (1, 2).
        assert_eq!(tri.faces[0], edge(1, 2));
        for (a, b) in [(0, 1), (0, 2), (1, 2)] {
            assert_eq!(c.simplices(1)[edge(a, b) as usize].parents, [0]);
        }
        for (a, b) in [(2, 3), (3, 4)] {
            assert!(c.simplices(1)[edge(a, b) as usize].parents.is_empty());
        }
        // Vertex 2's parents are those three edges; the point 5 is given (+1) and parentless.
        let mut at2 = c.simplices(0)[2].parents.clone();
        at2.sort_unstable();
        let mut e2 = vec![edge(0, 2), edge(1, 2), edge(2, 3)];
        e2.sort_unstable();
        assert_eq!(at2, e2);
        assert_eq!(c.simplices(0)[5].sign, 1);
        assert!(c.simplices(0)[5].parents.is_empty());
    }

    #[test]
    fn polyline_edge_pairs_share_the_middle_vertex() {
        let c = curve(4, &[[0, 1], [1, 2], [2, 3]]);
        assert_eq!(c.edge_pairs(), [[0, 1, 2], [1, 2, 3]]);
        assert_eq!(c.boundary(0), [0, 3]);
        let reversed = curve(4, &[[3, 2], [2, 1], [1, 0]]);
        assert_eq!(reversed.edge_pairs(), [[0, 1, 2], [1, 2, 3]]);
        assert!(!c.is_closed());
        assert!(c.isolated_points().is_empty());
    }

    #[test]
    fn star_vertex_pairs_every_curve_edge() {
        let c = curve(4, &[[0, 3], [0, 1], [2, 0]]);
        assert_eq!(c.edge_pairs(), [[1, 0, 2], [1, 0, 3], [2, 0, 3]]);
    }

    #[test]
    fn surface_edges_make_no_edge_pairs() {
        assert!(surface(9, &grid(3)).edge_pairs().is_empty());
    }

    #[test]
    fn out_of_range_vertex_names_the_element() {
        let err = Complex::build(3, &[], &[[0, 1]], &[[0, 1, 2], [0, 1, 9]], &[]).unwrap_err();
        assert_eq!(
            err,
            ComplexError::VertexOutOfRange {
                list: "triangles",
                element: 1,
                vertex: 9,
                n_vertices: 3,
            }
        );
        assert_eq!(
            err.to_string(),
            "triangles[1] refers to vertex 9, but the object has 3 vertices"
        );
        let err = Complex::build(3, &[7], &[], &[], &[]).unwrap_err();
        assert!(err.to_string().starts_with("points[0]"), "{err}");
        let err = Complex::build(0, &[], &[], &[], &[[0, 1, 2, 3]]).unwrap_err();
        assert!(err.to_string().starts_with("tets[0]"), "{err}");
    }

    #[test]
    fn repeated_vertex_is_degenerate() {
        let err = Complex::build(4, &[], &[[0, 1], [3, 3]], &[], &[]).unwrap_err();
        assert_eq!(
            err.to_string(),
            "edges[1] = [3, 3] repeats vertex 3 (a degenerate simplex)"
        );
        let err = Complex::build(4, &[], &[], &[[1, 1, 2]], &[]).unwrap_err();
        assert_eq!(
            err,
            ComplexError::RepeatedVertex {
                list: "triangles",
                element: 0,
                vertices: vec![1, 1, 2],
                vertex: 1,
            }
        );
        let err = Complex::build(4, &[], &[], &[], &[[0, 1, 2, 0]]).unwrap_err();
        assert!(
            err.to_string().starts_with("tets[0] = [0, 1, 2, 0]"),
            "{err}"
        );
    }

    #[test]
    fn empty_complex_has_only_vertices() {
        let c = Complex::build(3, &[], &[], &[], &[]).unwrap();
        assert_eq!(c.n_vertices(), 3);
        assert_eq!(c.count(0), 3);
        assert_eq!(c.isolated_points(), [0, 1, 2]);
        assert!(!c.is_closed());
        assert!(c.is_manifold());
        assert!(c.simplices(4).is_empty());
        assert_eq!(c.count(9), 0);
        assert!(Complex::build(0, &[], &[], &[], &[])
            .unwrap()
            .edges()
            .is_empty());
    }

    #[test]
    fn building_twice_gives_identical_output() {
        let triangles = grid(6);
        let tets = [[36, 37, 38, 39], [37, 38, 39, 40], [39, 38, 37, 41]];
        let edges = [[41, 42], [42, 43], [43, 41], [7, 8]];
        let build = || Complex::build(45, &[44], &edges, &triangles, &tets).unwrap();
        let (a, b) = (build(), build());
        assert_eq!(a, b);
        assert_eq!(a.edges(), b.edges());
        assert_eq!(a.triangles_oriented(), b.triangles_oriented());
        assert_eq!(a.tets(), b.tets());
        assert_eq!(a.triangle_pairs(), b.triangle_pairs());
        assert_eq!(a.edge_pairs(), b.edge_pairs());
        assert_eq!(a.boundary_edges(), b.boundary_edges());
        assert_eq!(a.isolated_points(), [44]);
    }
}
