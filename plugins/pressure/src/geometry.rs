//! The geometry of one chamber as pure functions: its enclosed volume (closed surfaces, and
//! open ones capped over their boundary loops), the area of its openings, and the
//! **pressure normals** `gᵢ` along which pressure pushes each vertex. Everything the solver
//! does with positions goes through [`Surface::measure`]; it is tested here against finite
//! differences and the identities it rests on.
//!
//! See the [crate docs](crate#geometry) for the theory.

use glam::DVec3;

/// One chamber's surface, in local vertex indices: `vertices[l]` is the global particle index
/// of local vertex `l`.
#[derive(Clone, Copy, Debug)]
pub struct Surface<'a> {
    /// Global particle index of each local vertex.
    pub vertices: &'a [u32],
    /// Consistently oriented triangles (local indices); outward for a closed surface.
    pub triangles: &'a [[u32; 3]],
    /// The same triangles in global particle indices (`vertices[l]` for each corner `l`), so
    /// the volume reads positions without a second indirection.
    pub corners: &'a [[u32; 3]],
    /// Boundary loops as `[start, end)` ranges into `loop_vertices`; empty for a closed
    /// surface.
    pub loops: &'a [[u32; 2]],
    /// Local vertex indices of every loop, each loop in the direction its triangles
    /// traverse it.
    pub loop_vertices: &'a [u32],
}

/// What [`Surface::measure`] finds.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Measure {
    /// Enclosed volume (m³): of the surface itself if closed, else of the surface closed by a
    /// fan from each boundary loop's centroid. Positive for an outward orientation.
    pub volume: f64,
    /// Total area of the openings (m²): the magnitude of each loop's vector area, summed.
    pub open_area: f64,
}

/// A cubic polynomial `c₀ + c₁t + c₂t² + c₃t³`: the volume along a line of displacements.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Cubic {
    /// Coefficients, constant first.
    pub c: [f64; 4],
}

impl Cubic {
    /// The value at `t`.
    #[inline]
    pub fn at(&self, t: f64) -> f64 {
        let [c0, c1, c2, c3] = self.c;
        c0 + t * (c1 + t * (c2 + t * c3))
    }

    /// The derivative at `t`.
    #[inline]
    pub fn slope(&self, t: f64) -> f64 {
        let [_, c1, c2, c3] = self.c;
        c1 + t * (2.0 * c2 + t * 3.0 * c3)
    }
}

/// `(a − r)·((b − r) × (c − r)) / 6`: the signed volume of the tetrahedron `(r, a, b, c)`.
#[inline]
fn tet_volume(r: DVec3, a: DVec3, b: DVec3, c: DVec3) -> f64 {
    (a - r).dot((b - r).cross(c - r)) / 6.0
}

impl<'a> Surface<'a> {
    /// Whether the surface has no boundary.
    pub fn is_closed(&self) -> bool {
        self.loops.is_empty()
    }

    /// Position of local vertex `l`.
    #[inline]
    fn at(&self, x: &[DVec3], l: u32) -> DVec3 {
        x[self.vertices[l as usize] as usize]
    }

    /// The volume and opening area at positions `x` (global slice), and, if
    /// `normals` is given (one per local vertex), the pressure normals
    ///
    /// ```text
    /// gᵢ = Σ_{t ∋ i} Aₜ nₜ / 3 = Σ_{t = (i, j, k)} (xⱼ − xᵢ) × (xₖ − xᵢ) / 6     (m²)
    /// ```
    ///
    /// over the surface's own triangles (not the caps). For a closed surface `gᵢ = ∂V/∂xᵢ`
    /// exactly; for an open one it is the gradient of the capped volume at every vertex off
    /// the boundary, and at the boundary the force pressure exerts on the cloth alone.
    ///
    /// The volume is accumulated relative to the first vertex, so it does not lose digits
    /// far from the origin. Allocation-free. The caller guarantees every index is in range.
    pub fn measure(&self, x: &[DVec3], normals: Option<&mut [DVec3]>) -> Measure {
        let Some(&first) = self.vertices.first() else {
            return Measure::default();
        };
        let r = x[first as usize];
        let mut volume = 0.0;
        match normals {
            Some(g) => {
                g.fill(DVec3::ZERO);
                for (&[a, b, c], &[pa, pb, pc]) in self.triangles.iter().zip(self.corners) {
                    let (xa, xb, xc) = (x[pa as usize], x[pb as usize], x[pc as usize]);
                    volume += tet_volume(r, xa, xb, xc);
                    let e = (xb - xa).cross(xc - xa) / 6.0;
                    g[a as usize] += e;
                    g[b as usize] += e;
                    g[c as usize] += e;
                }
            }
            None => {
                for &[pa, pb, pc] in self.corners {
                    let (xa, xb, xc) = (x[pa as usize], x[pb as usize], x[pc as usize]);
                    volume += tet_volume(r, xa, xb, xc);
                }
            }
        }
        let mut open_area = 0.0;
        for &[start, end] in self.loops {
            let ring = &self.loop_vertices[start as usize..end as usize];
            if ring.is_empty() {
                continue;
            }
            let centroid = ring.iter().map(|&l| self.at(x, l)).sum::<DVec3>() / ring.len() as f64;
            let mut vector_area = DVec3::ZERO;
            for (k, &i) in ring.iter().enumerate() {
                let j = ring[(k + 1) % ring.len()];
                let (xi, xj) = (self.at(x, i), self.at(x, j));
                // The cap triangle (j, i, c) traverses the boundary edge i → j backwards, as
                // the neighbouring triangle of a closed, consistently oriented surface would.
                volume += tet_volume(r, xj, xi, centroid);
                vector_area += (xi - centroid).cross(xj - centroid);
            }
            open_area += 0.5 * vector_area.length();
        }
        Measure { volume, open_area }
    }

    /// The area of the surface itself (m²), caps excluded.
    pub fn area(&self, x: &[DVec3]) -> f64 {
        let doubled: f64 = self
            .corners
            .iter()
            .map(|&[a, b, c]| {
                let (xa, xb, xc) = (x[a as usize], x[b as usize], x[c as usize]);
                (xb - xa).cross(xc - xa).length()
            })
            .sum();
        0.5 * doubled
    }

    /// The enclosed volume alone (m³), as [`measure`](Self::measure) computes it: the hot
    /// loop of every projection (one triple product per triangle and per cap triangle).
    pub fn volume(&self, x: &[DVec3]) -> f64 {
        let Some(&first) = self.vertices.first() else {
            return 0.0;
        };
        let r = x[first as usize];
        let mut volume = 0.0;
        for &[pa, pb, pc] in self.corners {
            volume += tet_volume(r, x[pa as usize], x[pb as usize], x[pc as usize]);
        }
        for &[start, end] in self.loops {
            let ring = &self.loop_vertices[start as usize..end as usize];
            if ring.is_empty() {
                continue;
            }
            let centroid = ring.iter().map(|&l| self.at(x, l)).sum::<DVec3>() / ring.len() as f64;
            for (k, &i) in ring.iter().enumerate() {
                let j = ring[(k + 1) % ring.len()];
                volume += tet_volume(r, self.at(x, j), self.at(x, i), centroid);
            }
        }
        volume
    }

    /// Once per substep, for displacements `Δxᵢ = t uᵢ` along fixed per-vertex directions `u`
    /// (local, one per vertex): fills `moments` with `mᵢ = Σ_{t = (i, j, k)} uⱼ × uₖ` (each
    /// triangle in its winding, cap triangles included, a cap centroid's share spread over
    /// its loop) and returns `Σₜ ua·(ub × uc)`, so that [`volume_along`](Self::volume_along)
    /// is linear in the positions per vertex. Allocation-free.
    pub fn line_moments(&self, u: &[DVec3], moments: &mut [DVec3]) -> f64 {
        moments.fill(DVec3::ZERO);
        let mut cubic = 0.0;
        for &[a, b, c] in self.triangles {
            let (ua, ub, uc) = (u[a as usize], u[b as usize], u[c as usize]);
            moments[a as usize] += ub.cross(uc);
            moments[b as usize] += uc.cross(ua);
            moments[c as usize] += ua.cross(ub);
            cubic += ua.dot(ub.cross(uc));
        }
        for &[start, end] in self.loops {
            let ring = &self.loop_vertices[start as usize..end as usize];
            if ring.is_empty() {
                continue;
            }
            let share = 1.0 / ring.len() as f64;
            let uc = ring.iter().map(|&l| u[l as usize]).sum::<DVec3>() * share;
            let mut centroid_moment = DVec3::ZERO;
            for (k, &i) in ring.iter().enumerate() {
                let j = ring[(k + 1) % ring.len()];
                // The cap triangle (j, i, c).
                let (uj, ui) = (u[j as usize], u[i as usize]);
                moments[j as usize] += ui.cross(uc);
                moments[i as usize] += uc.cross(uj);
                centroid_moment += uj.cross(ui);
                cubic += uj.dot(ui.cross(uc));
            }
            for &l in ring {
                moments[l as usize] += centroid_moment * share;
            }
        }
        cubic / 6.0
    }

    /// The enclosed volume along the line `x + t u`, exactly: `V(t) = c₀ + c₁t + c₂t² + c₃t³`
    /// (the volume is a cubic in the positions). `c₀ = V(x)`, `c₁ = Σ ∇ᵢV(x)·uᵢ` (the exact
    /// slope), `c₂ = Σ (xᵢ − r)·mᵢ / 6` with the `moments` of
    /// [`line_moments`](Self::line_moments), which also returned `c₃`. One pass: three cross
    /// products per triangle and a dot product per vertex.
    pub fn volume_along(&self, x: &[DVec3], u: &[DVec3], moments: &[DVec3], c3: f64) -> Cubic {
        let Some(&first) = self.vertices.first() else {
            return Cubic::default();
        };
        let r = x[first as usize];
        let (mut c0, mut c1) = (0.0, 0.0);
        let mut term = |a: DVec3, b: DVec3, c: DVec3, ua: DVec3, ub: DVec3, uc: DVec3| {
            let bc = b.cross(c);
            c0 += a.dot(bc);
            c1 += ua.dot(bc) + ub.dot(c.cross(a)) + uc.dot(a.cross(b));
        };
        for (&[a, b, c], &[pa, pb, pc]) in self.triangles.iter().zip(self.corners) {
            term(
                x[pa as usize] - r,
                x[pb as usize] - r,
                x[pc as usize] - r,
                u[a as usize],
                u[b as usize],
                u[c as usize],
            );
        }
        for &[start, end] in self.loops {
            let ring = &self.loop_vertices[start as usize..end as usize];
            if ring.is_empty() {
                continue;
            }
            let share = 1.0 / ring.len() as f64;
            let centroid = ring.iter().map(|&l| self.at(x, l)).sum::<DVec3>() * share - r;
            let uc = ring.iter().map(|&l| u[l as usize]).sum::<DVec3>() * share;
            for (k, &i) in ring.iter().enumerate() {
                let j = ring[(k + 1) % ring.len()];
                let (xj, xi) = (self.at(x, j) - r, self.at(x, i) - r);
                term(xj, xi, centroid, u[j as usize], u[i as usize], uc);
            }
        }
        let c2: f64 = self
            .vertices
            .iter()
            .zip(moments)
            .map(|(&p, m)| (x[p as usize] - r).dot(*m))
            .sum();
        Cubic {
            c: [c0 / 6.0, c1 / 6.0, c2 / 6.0, c3],
        }
    }

    /// Turns the pressure normals into the directions the vertices move along, in place:
    /// `uᵢ = wᵢ gᵢ` (m²/kg), with `w` the global inverse masses. A correction of multiplier
    /// `Δλ` then moves vertex `i` by `uᵢ Δλ`, the XPBD displacement `wᵢ ∇ᵢC Δλ`.
    pub fn weight(&self, normals: &mut [DVec3], inv_mass: &[f64]) {
        for (g, &p) in normals.iter_mut().zip(self.vertices) {
            *g *= inv_mass[p as usize];
        }
    }

    /// Moves every vertex by `Δxᵢ = uᵢ t` (or, for velocities, `Δvᵢ`). Kinematic vertices
    /// (`w = 0`) are never touched.
    pub fn displace(&self, x: &mut [DVec3], directions: &[DVec3], inv_mass: &[f64], t: f64) {
        for (&p, u) in self.vertices.iter().zip(directions) {
            let p = p as usize;
            if inv_mass[p] > 0.0 {
                x[p] += *u * t;
            }
        }
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    pub(crate) use nucleus_sdk::testing::Rng;

    /// An owned surface for the tests.
    pub(crate) struct Mesh {
        pub x: Vec<DVec3>,
        pub vertices: Vec<u32>,
        pub triangles: Vec<[u32; 3]>,
        pub corners: Vec<[u32; 3]>,
        pub loops: Vec<[u32; 2]>,
        pub loop_vertices: Vec<u32>,
    }

    impl Mesh {
        /// Sets `corners` from `triangles` and `vertices`.
        pub fn index(mut self) -> Self {
            let v = &self.vertices;
            self.corners = self
                .triangles
                .iter()
                .map(|t| t.map(|l| v[l as usize]))
                .collect();
            self
        }

        pub fn surface(&self) -> Surface<'_> {
            Surface {
                vertices: &self.vertices,
                triangles: &self.triangles,
                corners: &self.corners,
                loops: &self.loops,
                loop_vertices: &self.loop_vertices,
            }
        }

        /// The axis-aligned box `[0, a] × [0, b] × [0, c]`, outward, 8 vertices.
        pub fn cuboid(a: f64, b: f64, c: f64) -> Self {
            let x = (0..8)
                .map(|k| {
                    DVec3::new(
                        a * (k & 1) as f64,
                        b * ((k >> 1) & 1) as f64,
                        c * ((k >> 2) & 1) as f64,
                    )
                })
                .collect();
            // Faces as quads (outward), split in two.
            let quads = [
                [0, 2, 3, 1], // z = 0
                [4, 5, 7, 6], // z = c
                [0, 1, 5, 4], // y = 0
                [2, 6, 7, 3], // y = b
                [0, 4, 6, 2], // x = 0
                [1, 3, 7, 5], // x = a
            ];
            let triangles = quads
                .iter()
                .flat_map(|&[p, q, r, s]| [[p, q, r], [p, r, s]])
                .collect();
            Self {
                x,
                vertices: (0..8).collect(),
                triangles,
                corners: Vec::new(),
                loops: Vec::new(),
                loop_vertices: Vec::new(),
            }
            .index()
        }

        /// The cuboid without its top face (z = c): an open box, one loop 4 → 5 → 7 → 6
        /// backwards (as the side triangles traverse it).
        pub fn open_box(a: f64, b: f64, c: f64) -> Self {
            let mut m = Self::cuboid(a, b, c);
            m.triangles.drain(2..4);
            m.loops = vec![[0, 4]];
            m.loop_vertices = vec![4, 6, 7, 5];
            m.index()
        }

        /// A UV sphere of `rings × segments` with poles, outward.
        pub fn uv_sphere(radius: f64, rings: u32, segments: u32) -> Self {
            let mut x = vec![DVec3::new(0.0, 0.0, radius)];
            for r in 1..rings {
                let theta = std::f64::consts::PI * r as f64 / rings as f64;
                for s in 0..segments {
                    let phi = 2.0 * std::f64::consts::PI * s as f64 / segments as f64;
                    x.push(
                        radius
                            * DVec3::new(
                                theta.sin() * phi.cos(),
                                theta.sin() * phi.sin(),
                                theta.cos(),
                            ),
                    );
                }
            }
            x.push(DVec3::new(0.0, 0.0, -radius));
            let south = x.len() as u32 - 1;
            let ring = |r: u32, s: u32| 1 + (r - 1) * segments + s % segments;
            let mut triangles = Vec::new();
            for s in 0..segments {
                triangles.push([0, ring(1, s), ring(1, s + 1)]);
                for r in 1..rings - 1 {
                    let (a, b) = (ring(r, s), ring(r, s + 1));
                    let (c, d) = (ring(r + 1, s), ring(r + 1, s + 1));
                    triangles.push([a, c, d]);
                    triangles.push([a, d, b]);
                }
                triangles.push([ring(rings - 1, s), south, ring(rings - 1, s + 1)]);
            }
            Self {
                vertices: (0..x.len() as u32).collect(),
                x,
                triangles,
                corners: Vec::new(),
                loops: Vec::new(),
                loop_vertices: Vec::new(),
            }
            .index()
        }

        pub fn measure(&self) -> Measure {
            self.surface().measure(&self.x, None)
        }

        pub fn normals(&self) -> Vec<DVec3> {
            let mut g = vec![DVec3::ZERO; self.vertices.len()];
            self.surface().measure(&self.x, Some(&mut g));
            g
        }

        /// Random jiggle of every vertex by up to `half` per axis.
        pub fn jiggle(&mut self, rng: &mut Rng, half: f64) {
            for p in &mut self.x {
                *p += rng.vec3(half);
            }
        }
    }

    #[test]
    fn cuboid_volume_and_area_are_exact() {
        let m = Mesh::cuboid(1.0, 2.0, 3.0);
        let r = m.measure();
        assert!((r.volume - 6.0).abs() < 1e-14, "{r:?}");
        assert!((m.surface().area(&m.x) - 22.0).abs() < 1e-14);
        assert_eq!(r.open_area, 0.0);
        // Far from the origin the volume keeps its digits.
        let mut far = Mesh::cuboid(1.0, 2.0, 3.0);
        for p in &mut far.x {
            *p += DVec3::new(1e6, -2e6, 3e6);
        }
        assert!((far.measure().volume - 6.0).abs() < 1e-9);
    }

    #[test]
    fn volume_alone_is_the_measured_volume() {
        let mut rng = Rng(5);
        for mut m in [Mesh::open_box(1.0, 2.0, 0.5), Mesh::uv_sphere(0.4, 5, 9)] {
            m.jiggle(&mut rng, 0.1);
            assert_eq!(m.surface().volume(&m.x), m.measure().volume);
        }
    }

    #[test]
    fn the_volume_along_a_line_is_an_exact_cubic() {
        let mut rng = Rng(31);
        for mut m in [Mesh::uv_sphere(0.4, 5, 9), Mesh::open_box(1.0, 2.0, 0.5)] {
            m.jiggle(&mut rng, 0.1);
            let u: Vec<DVec3> = m.x.iter().map(|_| rng.vec3(0.3)).collect();
            let mut moments = vec![DVec3::ZERO; m.x.len()];
            let c3 = m.surface().line_moments(&u, &mut moments);
            let cubic = m.surface().volume_along(&m.x, &u, &moments, c3);
            for t in [0.0, 0.3, -0.7, 1.9] {
                let moved: Vec<DVec3> = m.x.iter().zip(&u).map(|(x, u)| *x + *u * t).collect();
                let exact = m.surface().volume(&moved);
                assert!(
                    (cubic.at(t) - exact).abs() < 1e-13,
                    "t {t}: {} vs {exact}",
                    cubic.at(t)
                );
            }
            // The slope at 0 is the gradient along u.
            let g = m.normals();
            let slope: f64 = g.iter().zip(&u).map(|(g, u)| g.dot(*u)).sum();
            if m.loops.is_empty() {
                assert!(
                    (cubic.slope(0.0) - slope).abs() < 1e-13,
                    "{} vs {slope}",
                    cubic.slope(0.0)
                );
            }
        }
    }

    #[test]
    fn open_box_is_capped_over_its_boundary_loop() {
        // The top of the box is missing; the cap over the loop (a flat square) restores the
        // full volume, and the opening is the missing face.
        let m = Mesh::open_box(1.0, 2.0, 3.0);
        let r = m.measure();
        assert!((r.volume - 6.0).abs() < 1e-14, "{r:?}");
        assert!((r.open_area - 2.0).abs() < 1e-14, "{r:?}");
        assert!((m.surface().area(&m.x) - 20.0).abs() < 1e-14);
    }

    #[test]
    fn sphere_volume_converges_to_four_thirds_pi_r_cubed() {
        let exact = 4.0 / 3.0 * std::f64::consts::PI;
        let coarse = (Mesh::uv_sphere(1.0, 16, 32).measure().volume - exact).abs();
        let fine = (Mesh::uv_sphere(1.0, 64, 128).measure().volume - exact).abs();
        assert!(coarse < 0.03 * exact && fine < 0.002 * exact);
        // Second order: four times the resolution, sixteen times smaller error (±20 %).
        assert!((coarse / fine - 16.0).abs() < 3.2, "{}", coarse / fine);
    }

    #[test]
    fn reversed_orientation_negates_the_volume() {
        let mut m = Mesh::uv_sphere(0.5, 6, 8);
        let v = m.measure().volume;
        for t in &mut m.triangles {
            t.swap(1, 2);
        }
        let m = m.index();
        assert!((m.measure().volume + v).abs() < 1e-15 && v > 0.0);
    }

    /// Central differences of the (capped) volume at local vertex `l`.
    fn fd_gradient(m: &mut Mesh, l: usize) -> DVec3 {
        let eps = 1e-6;
        let mut g = DVec3::ZERO;
        for axis in 0..3 {
            let p = m.vertices[l] as usize;
            let keep = m.x[p];
            m.x[p][axis] = keep[axis] + eps;
            let plus = m.measure().volume;
            m.x[p][axis] = keep[axis] - eps;
            let minus = m.measure().volume;
            m.x[p] = keep;
            g[axis] = (plus - minus) / (2.0 * eps);
        }
        g
    }

    #[test]
    fn normals_are_the_volume_gradient_of_a_closed_surface() {
        let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
        for _ in 0..20 {
            let mut m = Mesh::uv_sphere(rng.range(0.2, 2.0), 5, 7);
            m.jiggle(&mut rng, 0.1);
            let g = m.normals();
            let scale = g.iter().map(|g| g.length()).fold(0.0, f64::max);
            for (l, g) in g.iter().enumerate() {
                let fd = fd_gradient(&mut m, l);
                assert!((fd - *g).length() < 1e-7 * scale, "vertex {l}: {fd} vs {g}");
            }
        }
    }

    #[test]
    fn normals_are_the_capped_volume_gradient_off_the_boundary() {
        let mut rng = Rng(7);
        for _ in 0..20 {
            let mut m = Mesh::open_box(1.0, 1.5, 0.7);
            m.jiggle(&mut rng, 0.15);
            let g = m.normals();
            // Vertices 0..4 (the bottom) are off the boundary; 4..8 are on the loop.
            for (l, g) in g.iter().enumerate().take(4) {
                let fd = fd_gradient(&mut m, l);
                assert!((fd - *g).length() < 1e-7, "vertex {l}: {fd} vs {g}");
            }
        }
    }

    #[test]
    fn normals_of_a_closed_surface_sum_to_zero_force_and_torque() {
        // Σ gᵢ = Σ Aₜ nₜ = 0 and Σ xᵢ × gᵢ = Σ cₜ × Aₜ nₜ = 0 on any closed polyhedron: a
        // uniform pressure exerts no net force nor torque, whatever the masses.
        let mut rng = Rng(99);
        for _ in 0..20 {
            let mut m = Mesh::uv_sphere(1.0, 7, 9);
            m.jiggle(&mut rng, 0.3);
            for p in &mut m.x {
                *p += DVec3::new(3.0, -1.0, 2.0);
            }
            let g = m.normals();
            let scale: f64 = g.iter().map(|g| g.length()).sum();
            let force: DVec3 = g.iter().sum();
            let torque: DVec3 = m.x.iter().zip(&g).map(|(x, g)| x.cross(*g)).sum();
            assert!(force.length() < 1e-14 * scale, "{force}");
            assert!(torque.length() < 1e-13 * scale, "{torque}");
        }
    }

    #[test]
    fn a_step_along_frozen_normals_conserves_momentum_with_any_masses() {
        // Δxᵢ = wᵢ gᵢ s with g frozen at x0: Σ mᵢ Δxᵢ = s Σ gᵢ = 0 and
        // Σ mᵢ x0ᵢ × Δxᵢ = s Σ x0ᵢ × gᵢ = 0, whatever the masses (1 g to 1 t here), so the
        // discrete momenta of the step, Σ m (x − x0)/h and Σ m x0 × x / h, do not change.
        let mut rng = Rng(2024);
        for _ in 0..20 {
            let mut m = Mesh::uv_sphere(0.3, 6, 8);
            m.jiggle(&mut rng, 0.05);
            let g = m.normals();
            let w: Vec<f64> = (0..m.x.len())
                .map(|_| 10f64.powf(rng.range(-3.0, 3.0)))
                .collect();
            let mut u = g.clone();
            m.surface().weight(&mut u, &w);
            let mut x = m.x.clone();
            let s = rng.range(-1e-3, 1e-3);
            m.surface().displace(&mut x, &u, &w, s);
            // Up to the rounding of the positions themselves (ε|x| per coordinate).
            let (mut p, mut l, mut p_floor, mut l_floor) = (DVec3::ZERO, DVec3::ZERO, 0.0, 0.0);
            for ((x1, x0), w) in x.iter().zip(&m.x).zip(&w) {
                let m_dx = (*x1 - *x0) / *w;
                p += m_dx;
                l += x0.cross(m_dx);
                let rounding = 4.0 * f64::EPSILON * x0.length() / *w;
                p_floor += m_dx.length() * 1e-14 + rounding;
                l_floor += x0.length() * (m_dx.length() * 1e-14 + rounding);
            }
            assert!(p.length() < p_floor, "{p} vs {p_floor}");
            assert!(l.length() < l_floor, "{l} vs {l_floor}");
        }
    }

    #[test]
    fn normals_of_an_open_surface_sum_to_its_vector_area() {
        // The open box pushed from inside: the net force is the pressure times the missing
        // face's area, along the opening's outward normal reversed (−z).
        let m = Mesh::open_box(1.0, 2.0, 3.0);
        let force: DVec3 = m.normals().iter().sum();
        assert!(
            (force - DVec3::new(0.0, 0.0, -2.0)).length() < 1e-14,
            "{force}"
        );
    }

    #[test]
    fn degenerate_surfaces_measure_finite_zeros() {
        // Every vertex at one point, and a flat closed surface (zero volume).
        let mut m = Mesh::uv_sphere(1.0, 4, 6);
        for p in &mut m.x {
            *p = DVec3::new(0.3, 0.3, 0.3);
        }
        let r = m.measure();
        assert_eq!((r.volume, r.open_area), (0.0, 0.0));
        assert_eq!(m.surface().area(&m.x), 0.0);
        assert!(m.normals().iter().all(|g| *g == DVec3::ZERO));
        let mut flat = Mesh::uv_sphere(1.0, 4, 6);
        for p in &mut flat.x {
            p.z = 0.0;
        }
        let r = flat.measure();
        assert!(
            r.volume.abs() < 1e-15 && flat.surface().area(&flat.x) > 0.0,
            "{r:?}"
        );
        assert!(flat.normals().iter().all(|g| g.is_finite()));
    }

    #[test]
    fn displacement_moves_only_dynamic_vertices_along_w_g() {
        let m = Mesh::cuboid(1.0, 1.0, 1.0);
        let g = m.normals();
        let mut w = vec![2.0; 8];
        w[3] = 0.0;
        let mut u = g.clone();
        m.surface().weight(&mut u, &w);
        let mut x = m.x.clone();
        m.surface().displace(&mut x, &u, &w, 0.1);
        assert_eq!(x[3], m.x[3]);
        for l in [0, 1, 2, 4, 5, 6, 7] {
            assert!((x[l] - m.x[l] - g[l] * 0.2).length() < 1e-15);
        }
    }
}
