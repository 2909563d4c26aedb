//! Procedural shapes and mesh import: each returns a [`Geometry`] (rest positions and
//! simplices in local vertex indices).

use glam::DVec3;

use crate::scene::{Geometry, Plane};

/// A grid cloth of `res = [nu, nv]` vertices; vertex `(i, j)` (row `i` along V, column `j`
/// along U) has index `i·nu + j` and sits at `origin + j·du·U + i·dv·V`. Each quad is split
/// along the same diagonal into triangles wound so their normal is `U × V`.
pub fn grid(size: [f64; 2], res: [u32; 2], plane: Plane, origin: [f64; 3]) -> Geometry {
    let [nu, nv] = res;
    let (u, v) = match plane {
        Plane::Xz => (DVec3::X, DVec3::Z),
        Plane::Xy => (DVec3::X, DVec3::Y),
        Plane::Yz => (DVec3::Y, DVec3::Z),
    };
    let du = size[0] / (nu - 1) as f64;
    let dv = size[1] / (nv - 1) as f64;
    let o = DVec3::from_array(origin);
    let mut positions = Vec::with_capacity((nu * nv) as usize);
    for i in 0..nv {
        for j in 0..nu {
            positions.push((o + u * (j as f64 * du) + v * (i as f64 * dv)).to_array());
        }
    }
    let mut triangles = Vec::with_capacity(2 * ((nu - 1) * (nv - 1)) as usize);
    for i in 0..nv - 1 {
        for j in 0..nu - 1 {
            let a = i * nu + j;
            let b = a + 1;
            let c = a + nu;
            let d = c + 1;
            triangles.push([a, b, d]);
            triangles.push([a, d, c]);
        }
    }
    Geometry {
        positions,
        triangles,
        grid: Some([nu, nv]),
        ..Geometry::default()
    }
}

/// A polyline of `segments` equal edges from `start` to `end`. If `length` exceeds the
/// distance between the ends, the rope is laid out as a V hanging below the line between
/// them (in the vertical plane through it; "below" is −y), so both ends can be pinned with
/// slack.
pub fn rope(start: [f64; 3], end: [f64; 3], segments: u32, length: Option<f64>) -> Geometry {
    let (a, b) = (DVec3::from_array(start), DVec3::from_array(end));
    let span = (b - a).length();
    let n = segments as f64;
    let positions = match length {
        Some(l) if l > span => {
            let along = if span > 0.0 { (b - a) / span } else { DVec3::X };
            let side = along.cross(DVec3::Y);
            let down = if side.length_squared() > 1e-12 {
                side.cross(along).normalize() * -1.0
            } else {
                DVec3::X
            };
            let down = if down.y > 0.0 { -down } else { down };
            let depth = ((0.5 * l).powi(2) - (0.5 * span).powi(2)).max(0.0).sqrt();
            let mid = (a + b) * 0.5 + down * depth;
            (0..=segments)
                .map(|k| {
                    let s = k as f64 / n * l;
                    let p = if s <= 0.5 * l {
                        a.lerp(mid, s / (0.5 * l))
                    } else {
                        mid.lerp(b, (s - 0.5 * l) / (0.5 * l))
                    };
                    p.to_array()
                })
                .collect()
        }
        _ => (0..=segments)
            .map(|k| a.lerp(b, k as f64 / n).to_array())
            .collect(),
    };
    let edges = (0..segments).map(|k| [k, k + 1]).collect();
    Geometry {
        positions,
        edges,
        ..Geometry::default()
    }
}

/// A closed icosphere: an icosahedron subdivided `subdivisions` times, vertices projected on
/// the sphere, triangles wound counter-clockwise seen from outside (normals point out).
pub fn icosphere(center: [f64; 3], radius: f64, subdivisions: u32) -> Geometry {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut verts: Vec<DVec3> = [
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ]
    .iter()
    .map(|p| DVec3::from_array(*p).normalize())
    .collect();
    let mut tris: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..subdivisions {
        let mut midpoint: std::collections::BTreeMap<(u32, u32), u32> = Default::default();
        let mut mid = |a: u32, b: u32, verts: &mut Vec<DVec3>| -> u32 {
            let key = (a.min(b), a.max(b));
            *midpoint.entry(key).or_insert_with(|| {
                verts.push(((verts[a as usize] + verts[b as usize]) * 0.5).normalize());
                verts.len() as u32 - 1
            })
        };
        let mut next = Vec::with_capacity(tris.len() * 4);
        for [a, b, c] in tris {
            let ab = mid(a, b, &mut verts);
            let bc = mid(b, c, &mut verts);
            let ca = mid(c, a, &mut verts);
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        tris = next;
    }
    let c = DVec3::from_array(center);
    Geometry {
        positions: verts.iter().map(|v| (c + *v * radius).to_array()).collect(),
        triangles: tris,
        ..Geometry::default()
    }
}

/// Unconnected particles on a lattice filling the box `[min, max]`.
pub fn particle_block(min: [f64; 3], max: [f64; 3], count: [u32; 3]) -> Geometry {
    let step = |k: usize| {
        if count[k] > 1 {
            (max[k] - min[k]) / (count[k] - 1) as f64
        } else {
            0.0
        }
    };
    let mut positions = Vec::new();
    for z in 0..count[2] {
        for y in 0..count[1] {
            for x in 0..count[0] {
                positions.push([
                    min[0] + x as f64 * step(0),
                    min[1] + y as f64 * step(1),
                    min[2] + z as f64 * step(2),
                ]);
            }
        }
    }
    let points = (0..positions.len() as u32).collect();
    Geometry {
        positions,
        points,
        ..Geometry::default()
    }
}

/// A box of `res` cells per axis, each cut into six positively oriented tetrahedra around its
/// main diagonal (conforming across cells).
pub fn tet_box(min: [f64; 3], max: [f64; 3], res: [u32; 3]) -> Geometry {
    let [nx, ny, nz] = res;
    let id = |x: u32, y: u32, z: u32| (z * (ny + 1) + y) * (nx + 1) + x;
    let mut positions = Vec::new();
    for z in 0..=nz {
        for y in 0..=ny {
            for x in 0..=nx {
                positions.push([
                    min[0] + (max[0] - min[0]) * x as f64 / nx as f64,
                    min[1] + (max[1] - min[1]) * y as f64 / ny as f64,
                    min[2] + (max[2] - min[2]) * z as f64 / nz as f64,
                ]);
            }
        }
    }
    let mut tets = Vec::new();
    for z in 0..nz {
        for y in 0..ny {
            for x in 0..nx {
                // Corners by bit pattern (x, y, z).
                let c = |b: u32| id(x + (b & 1), y + ((b >> 1) & 1), z + ((b >> 2) & 1));
                let (v0, v7) = (c(0), c(7));
                // The six tets sharing the diagonal v0-v7, one per path 0 → a → b → 7.
                for [a, b] in [[1, 3], [3, 2], [2, 6], [6, 4], [4, 5], [5, 1]] {
                    tets.push([v0, c(a), c(b), v7]);
                }
            }
        }
    }
    // Make every tet positively oriented.
    for t in &mut tets {
        let p = |i: u32| DVec3::from_array(positions[i as usize]);
        let d = (p(t[1]) - p(t[0]))
            .cross(p(t[2]) - p(t[0]))
            .dot(p(t[3]) - p(t[0]));
        if d < 0.0 {
            t.swap(1, 2);
        }
    }
    Geometry {
        positions,
        tets,
        ..Geometry::default()
    }
}

pub use crate::obj::load_obj;

/// The volume a geometry encloses (m³): the sum of its tetrahedra's volumes, or else the volume
/// inside its triangles, which must form closed, consistently oriented surfaces (every edge
/// used once in each direction). Errors say why there is no volume.
pub fn enclosed_volume(geo: &Geometry) -> Result<f64, String> {
    let p = |i: u32| DVec3::from_array(geo.positions[i as usize]);
    if !geo.tets.is_empty() {
        return Ok(geo
            .tets
            .iter()
            .map(|t| {
                ((p(t[1]) - p(t[0]))
                    .cross(p(t[2]) - p(t[0]))
                    .dot(p(t[3]) - p(t[0])))
                .abs()
                    / 6.0
            })
            .sum());
    }
    if geo.triangles.is_empty() {
        return Err("the object has no triangles or tetrahedra to enclose a volume".into());
    }
    let mut directed: Vec<(u32, u32)> = geo
        .triangles
        .iter()
        .flat_map(|t| [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])])
        .collect();
    directed.sort_unstable();
    if directed.windows(2).any(|w| w[0] == w[1]) {
        return Err(
            "the surface is not consistently oriented (an edge is traversed twice the same way)"
                .into(),
        );
    }
    if directed
        .iter()
        .any(|&(a, b)| directed.binary_search(&(b, a)).is_err())
    {
        return Err("the surface is open (it has boundary edges)".into());
    }
    let origin = p(geo.triangles[0][0]);
    let volume: f64 = geo
        .triangles
        .iter()
        .map(|t| (p(t[0]) - origin).dot((p(t[1]) - origin).cross(p(t[2]) - origin)) / 6.0)
        .sum();
    Ok(volume.abs())
}

/// Vertices chosen by a named selector, or `None` if it does not apply to the shape.
pub fn select(name: &str, geo: &Geometry) -> Option<Vec<u32>> {
    let n = geo.positions.len() as u32;
    if name == "all" {
        return Some((0..n).collect());
    }
    if let Some([nu, nv]) = geo.grid {
        let at = |i: u32, j: u32| i * nu + j;
        let (kind, edge) = name.split_once(':')?;
        let line: Vec<u32> = match edge {
            "row0" => (0..nu).map(|j| at(0, j)).collect(),
            "rowN" => (0..nu).map(|j| at(nv - 1, j)).collect(),
            "col0" => (0..nv).map(|i| at(i, 0)).collect(),
            "colN" => (0..nv).map(|i| at(i, nu - 1)).collect(),
            _ => return None,
        };
        return match kind {
            "edge" => Some(line),
            "corners" => Some(vec![line[0], line[line.len() - 1]]),
            _ => None,
        };
    }
    if !geo.edges.is_empty() && geo.triangles.is_empty() {
        return match name {
            "start" => Some(vec![0]),
            "end" => Some(vec![n - 1]),
            "ends" => Some(vec![0, n - 1]),
            _ => None,
        };
    }
    None
}

/// Per-vertex masses of an object: `total` spread evenly, `density` lumped by the measure of
/// the highest-dimensional simplices (each simplex gives `density × measure / (k+1)` to each
/// of its vertices; vertices in no such simplex get the mean share), or a fixed vertex mass.
pub fn vertex_masses(
    geo: &Geometry,
    total: Option<f64>,
    density: Option<f64>,
    vertex: Option<f64>,
) -> Vec<f64> {
    let n = geo.positions.len();
    if let Some(m) = vertex {
        return vec![m; n];
    }
    let Some(rho) = density else {
        let total = total.unwrap_or(1.0);
        return vec![total / n as f64; n];
    };
    let p = |i: u32| DVec3::from_array(geo.positions[i as usize]);
    let mut mass = vec![0.0; n];
    let mut add = |verts: &[u32], measure: f64| {
        let share = rho * measure / verts.len() as f64;
        for &v in verts {
            mass[v as usize] += share;
        }
    };
    if !geo.tets.is_empty() {
        for t in &geo.tets {
            let vol = (p(t[1]) - p(t[0]))
                .cross(p(t[2]) - p(t[0]))
                .dot(p(t[3]) - p(t[0]))
                .abs()
                / 6.0;
            add(t, vol);
        }
    } else if !geo.triangles.is_empty() {
        for t in &geo.triangles {
            let area = 0.5 * (p(t[1]) - p(t[0])).cross(p(t[2]) - p(t[0])).length();
            add(t, area);
        }
    } else if !geo.edges.is_empty() {
        for e in &geo.edges {
            add(e, (p(e[1]) - p(e[0])).length());
        }
    }
    let positive: Vec<f64> = mass.iter().copied().filter(|&m| m > 0.0).collect();
    let fallback = if positive.is_empty() {
        rho
    } else {
        positive.iter().sum::<f64>() / positive.len() as f64
    };
    for m in &mut mass {
        if *m <= 0.0 {
            *m = fallback;
        }
    }
    mass
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grid_has_expected_counts_and_spacing() {
        let g = grid([1.0, 1.0], [3, 4], Plane::Xz, [0.0; 3]);
        assert_eq!(g.positions.len(), 12);
        assert_eq!(g.triangles.len(), 2 * 2 * 3);
        assert_eq!(g.positions[1], [0.5, 0.0, 0.0]);
        assert_eq!(g.positions[3], [0.0, 0.0, 1.0 / 3.0]);
    }

    #[test]
    fn grid_corner_selectors_pick_the_two_corners_of_an_edge() {
        let g = grid([1.0, 1.0], [4, 3], Plane::Xz, [0.0; 3]);
        assert_eq!(select("corners:row0", &g), Some(vec![0, 3]));
        assert_eq!(select("corners:rowN", &g), Some(vec![8, 11]));
        assert_eq!(select("edge:col0", &g), Some(vec![0, 4, 8]));
        assert_eq!(select("ends", &g), None);
    }

    #[test]
    fn enclosed_volumes_of_a_cube_a_sphere_and_tets_and_no_volume_of_open_or_flipped_surfaces() {
        // A unit cube, outward.
        let mut cube = Geometry {
            positions: (0..8)
                .map(|k| [(k & 1) as f64, ((k >> 1) & 1) as f64, ((k >> 2) & 1) as f64])
                .collect(),
            ..Geometry::default()
        };
        let quads = [
            [0, 2, 3, 1],
            [4, 5, 7, 6],
            [0, 1, 5, 4],
            [2, 6, 7, 3],
            [0, 4, 6, 2],
            [1, 3, 7, 5],
        ];
        for q in quads {
            cube.triangles.push([q[0], q[1], q[2]]);
            cube.triangles.push([q[0], q[2], q[3]]);
        }
        assert!((enclosed_volume(&cube).unwrap() - 1.0).abs() < 1e-15);
        // An icosphere's volume is below the ball's and converges to it.
        let s = icosphere([0.0; 3], 1.0, 4);
        let v = enclosed_volume(&s).unwrap();
        let ball = 4.0 / 3.0 * std::f64::consts::PI;
        assert!(v < ball && v > 0.99 * ball, "{v}");
        let t = tet_box([0.0; 3], [1.0, 2.0, 3.0], [2, 1, 3]);
        assert!((enclosed_volume(&t).unwrap() - 6.0).abs() < 1e-12);
        let mut open = cube.clone();
        open.triangles.pop();
        assert!(enclosed_volume(&open).unwrap_err().contains("open"));
        let mut flipped = cube.clone();
        flipped.triangles[0].swap(1, 2);
        assert!(enclosed_volume(&flipped).unwrap_err().contains("oriented"));
        assert!(enclosed_volume(&Geometry::default()).is_err());
    }

    #[test]
    fn tet_box_tets_are_positive_and_fill_the_volume() {
        let g = tet_box([0.0; 3], [1.0, 2.0, 3.0], [2, 1, 3]);
        assert_eq!(g.tets.len(), 6 * 6);
        let p = |i: u32| DVec3::from_array(g.positions[i as usize]);
        let mut vol = 0.0;
        for t in &g.tets {
            let d = (p(t[1]) - p(t[0]))
                .cross(p(t[2]) - p(t[0]))
                .dot(p(t[3]) - p(t[0]));
            assert!(d > 0.0);
            vol += d / 6.0;
        }
        assert!((vol - 6.0).abs() < 1e-12);
    }

    #[test]
    fn slack_rope_has_its_length_and_hangs_below_its_ends() {
        let r = rope([0.0; 3], [1.0, 0.0, 0.0], 10, Some(1.5));
        let p: Vec<DVec3> = r.positions.iter().map(|p| DVec3::from_array(*p)).collect();
        let len: f64 = p.windows(2).map(|w| (w[1] - w[0]).length()).sum();
        assert!((len - 1.5).abs() < 1e-12);
        assert!((p[10] - DVec3::X).length() < 1e-12);
        assert!(p[5].y < -0.5);
    }

    #[test]
    fn icosphere_is_closed_outward_and_on_the_sphere() {
        let g = icosphere([1.0, 2.0, 3.0], 0.5, 2);
        assert_eq!(g.triangles.len(), 20 * 16);
        assert_eq!(g.positions.len(), 10 * 16 + 2);
        let c = DVec3::new(1.0, 2.0, 3.0);
        let p = |i: u32| DVec3::from_array(g.positions[i as usize]);
        let mut volume = 0.0;
        for t in &g.triangles {
            volume += (p(t[0]) - c).dot((p(t[1]) - c).cross(p(t[2]) - c)) / 6.0;
        }
        let sphere = 4.0 / 3.0 * std::f64::consts::PI * 0.125;
        assert!(volume > 0.0, "outward winding gives a positive volume");
        assert!((volume - sphere).abs() / sphere < 0.05);
        for v in &g.positions {
            assert!(((DVec3::from_array(*v) - c).length() - 0.5).abs() < 1e-12);
        }
        let complex =
            crate::complex::Complex::build(g.positions.len(), &[], &[], &g.triangles, &[]).unwrap();
        assert!(complex.is_closed() && complex.is_manifold() && complex.orientation_consistent());
    }

    #[test]
    fn density_lumping_conserves_total_mass() {
        let g = grid([2.0, 1.0], [5, 5], Plane::Xy, [0.0; 3]);
        let m = vertex_masses(&g, None, Some(0.3), None);
        assert!((m.iter().sum::<f64>() - 0.6).abs() < 1e-12);
        let r = rope([0.0; 3], [3.0, 0.0, 0.0], 6, None);
        let m = vertex_masses(&r, None, Some(2.0), None);
        assert!((m.iter().sum::<f64>() - 6.0).abs() < 1e-12);
    }
}
