//! Each object's geometry from its shape table (a generated shape or an OBJ mesh, with an
//! animated sequence), and its pins and masses resolved to its vertices.

use std::path::Path;

use toml::Spanned;

use super::{ObjectSpec, PinSelector, Scene};
use crate::error::SceneError;

/// The simplices and rest positions of one built object (local vertex indices).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Geometry {
    /// Rest positions (m).
    pub positions: Vec<[f64; 3]>,
    /// Isolated points.
    pub points: Vec<u32>,
    /// Curve edges.
    pub edges: Vec<[u32; 2]>,
    /// Triangles.
    pub triangles: Vec<[u32; 3]>,
    /// Tetrahedra.
    pub tets: Vec<[u32; 4]>,
    /// Grid resolution, for grid selectors.
    pub grid: Option<[u32; 2]>,
    /// Positions per frame of an animated mesh (frame 0 first); empty if not animated.
    pub sequence: Vec<Vec<[f64; 3]>>,
}

impl Scene {
    /// Builds the geometry of an object (reads mesh files).
    pub fn geometry(&self, o: &ObjectSpec) -> Result<Geometry, SceneError> {
        let name = o.name.get_ref();
        let shapes = [
            o.grid.is_some(),
            o.rope.is_some(),
            o.particles.is_some(),
            o.tet_box.is_some(),
            o.mesh.is_some(),
            o.sphere.is_some(),
        ];
        let n_shapes = shapes.iter().filter(|&&b| b).count();
        if n_shapes != 1 {
            return Err(self.invalid(
                o.name.span(),
                format!(
                    "object `{name}` needs exactly one shape table (grid, rope, particles, tet_box, mesh, sphere), found {n_shapes}"
                ),
            ));
        }
        let finite3 = |v: &[f64; 3]| v.iter().all(|x| x.is_finite());
        if let Some(g) = &o.grid {
            let [nu, nv] = *g.resolution.get_ref();
            if nu < 2 || nv < 2 || (nu as u64) * (nv as u64) > 50_000_000 {
                return Err(self.invalid(
                    g.resolution.span(),
                    format!("object `{name}`: grid resolution must be at least 2 per side (and sane), found [{nu}, {nv}]"),
                ));
            }
            if !(g.size.iter().all(|s| s.is_finite() && *s > 0.0) && finite3(&g.origin)) {
                return Err(self.invalid(
                    o.name.span(),
                    format!("object `{name}`: grid size must be positive and origin finite"),
                ));
            }
            return Ok(crate::shapes::grid(g.size, [nu, nv], g.plane, g.origin));
        }
        if let Some(r) = &o.rope {
            let n = *r.segments.get_ref();
            if n == 0 || n > 50_000_000 {
                return Err(self.invalid(
                    r.segments.span(),
                    format!("object `{name}`: a rope needs at least 1 segment"),
                ));
            }
            if !(finite3(&r.start) && finite3(&r.end)) {
                return Err(self.invalid(
                    o.name.span(),
                    format!("object `{name}`: rope ends must be finite"),
                ));
            }
            if r.length.is_some_and(|l| !(l.is_finite() && l > 0.0)) {
                return Err(self.invalid(
                    r.segments.span(),
                    format!("object `{name}`: rope length must be positive"),
                ));
            }
            return Ok(crate::shapes::rope(r.start, r.end, n, r.length));
        }
        if let Some(p) = &o.particles {
            let c = *p.count.get_ref();
            if c.contains(&0) || c.iter().map(|&x| x as u64).product::<u64>() > 50_000_000 {
                return Err(self.invalid(
                    p.count.span(),
                    format!("object `{name}`: particle count must be at least 1 per axis"),
                ));
            }
            if !(finite3(&p.min) && finite3(&p.max)) {
                return Err(self.invalid(
                    o.name.span(),
                    format!("object `{name}`: particle box must be finite"),
                ));
            }
            return Ok(crate::shapes::particle_block(p.min, p.max, c));
        }
        if let Some(t) = &o.tet_box {
            let r = *t.resolution.get_ref();
            if r.contains(&0) || r.iter().map(|&x| x as u64).product::<u64>() > 10_000_000 {
                return Err(self.invalid(
                    t.resolution.span(),
                    format!("object `{name}`: tet_box resolution must be at least 1 per axis"),
                ));
            }
            let ok =
                (0..3).all(|k| t.min[k].is_finite() && t.max[k].is_finite() && t.max[k] > t.min[k]);
            if !ok {
                return Err(self.invalid(
                    o.name.span(),
                    format!("object `{name}`: tet_box needs finite min < max"),
                ));
            }
            return Ok(crate::shapes::tet_box(t.min, t.max, r));
        }
        if let Some(sp) = &o.sphere {
            let n = *sp.subdivisions.get_ref();
            if n > 7 {
                return Err(self.invalid(
                    sp.subdivisions.span(),
                    format!("object `{name}`: at most 7 subdivisions (327,682 vertices)"),
                ));
            }
            if !(finite3(&sp.center) && sp.radius.is_finite() && sp.radius > 0.0) {
                return Err(self.invalid(
                    o.name.span(),
                    format!("object `{name}`: sphere needs a finite center and a positive radius"),
                ));
            }
            return Ok(crate::shapes::icosphere(sp.center, sp.radius, n));
        }
        let m = o.mesh.as_ref().expect("exactly one shape is set");
        let rel = m.path.get_ref();
        let full = self
            .path
            .parent()
            .map_or_else(|| rel.clone(), |d| d.join(rel));
        if !(m.scale.is_finite() && m.scale > 0.0 && finite3(&m.translate)) {
            return Err(self.invalid(
                m.path.span(),
                format!("object `{name}`: mesh scale must be positive and translate finite"),
            ));
        }
        let mut geo = crate::shapes::load_obj(&full, m.scale, m.translate).map_err(|e| {
            self.invalid(
                m.path.span(),
                format!("object `{name}`: mesh {}: {e}", full.display()),
            )
        })?;
        if let Some(pattern) = &m.sequence {
            let dir = self
                .path
                .parent()
                .map(Path::to_path_buf)
                .unwrap_or_default();
            for frame in 0..=self.file.solver.frames {
                let file = dir.join(
                    pattern
                        .get_ref()
                        .replace("{frame:04}", &format!("{frame:04}"))
                        .replace("{frame}", &frame.to_string()),
                );
                if !file.is_file() {
                    if frame == 0 {
                        geo.sequence.push(geo.positions.clone());
                        continue;
                    }
                    break;
                }
                let g = crate::shapes::load_obj(&file, m.scale, m.translate).map_err(|e| {
                    self.invalid(
                        pattern.span(),
                        format!("object `{name}`: mesh {}: {e}", file.display()),
                    )
                })?;
                if g.positions.len() != geo.positions.len() || g.triangles != geo.triangles {
                    return Err(self.invalid(
                        pattern.span(),
                        format!(
                            "object `{name}`: {} does not have the same vertices and faces as {}",
                            file.display(),
                            full.display()
                        ),
                    ));
                }
                geo.sequence.push(g.positions);
            }
            if geo.sequence.len() < 2 {
                return Err(self.invalid(
                    pattern.span(),
                    format!(
                        "object `{name}`: no files match the sequence `{}`",
                        pattern.get_ref()
                    ),
                ));
            }
        }
        Ok(geo)
    }

    /// Resolves the pins of an object to local vertex indices (sorted, unique).
    pub fn pins(&self, o: &ObjectSpec, geo: &Geometry) -> Result<Vec<u32>, SceneError> {
        match &o.pins {
            Some(pins) => self.select(o, pins, geo, "pin"),
            None => Ok(Vec::new()),
        }
    }

    /// The object's per-vertex masses: `mass`, `density` or `vertex_mass`, then its mass maps.
    pub fn masses(&self, o: &ObjectSpec, geo: &Geometry) -> Result<Vec<f64>, SceneError> {
        let mut masses = match &o.solid_density {
            Some(rho) => {
                let volume = crate::shapes::enclosed_volume(geo).map_err(|e| {
                    self.invalid(
                        rho.span(),
                        format!("object `{}`: solid_density: {e}", o.name.get_ref()),
                    )
                })?;
                let lumped = crate::shapes::vertex_masses(geo, None, Some(1.0), None);
                let sum: f64 = lumped.iter().sum();
                lumped
                    .iter()
                    .map(|m| m / sum * rho.get_ref() * volume)
                    .collect()
            }
            None => crate::shapes::vertex_masses(
                geo,
                o.mass.as_ref().map(|m| *m.get_ref()),
                o.density.as_ref().map(|m| *m.get_ref()),
                o.vertex_mass.as_ref().map(|m| *m.get_ref()),
            ),
        };
        for map in &o.mass_maps {
            for i in self.select(o, &map.vertices, geo, "mass map")? {
                masses[i as usize] *= *map.scale.get_ref();
            }
        }
        Ok(masses)
    }

    /// Resolves vertex selectors of an object to local vertex indices (sorted, unique);
    /// errors name the object and `what` selects.
    fn select(
        &self,
        o: &ObjectSpec,
        selectors: &Spanned<Vec<PinSelector>>,
        geo: &Geometry,
        what: &str,
    ) -> Result<Vec<u32>, SceneError> {
        let n = geo.positions.len();
        let name = o.name.get_ref();
        let mut out = Vec::new();
        let pins = selectors;
        for sel in pins.get_ref() {
            match sel {
                PinSelector::Index(i) => {
                    if *i < 0 || *i as usize >= n {
                        return Err(self.invalid(
                            pins.span(),
                            format!("object `{name}`: {what} index {i} is out of range (the object has {n} vertices)"),
                        ));
                    }
                    out.push(*i as u32);
                }
                PinSelector::Named(s) => {
                    let found = crate::shapes::select(s, geo).ok_or_else(|| {
                        self.invalid(
                            pins.span(),
                            format!("object `{name}`: unknown {what} selector `{s}` for this shape (grids: corners:row0|rowN|col0|colN, edge:...; ropes: start, end, ends; any: all)"),
                        )
                    })?;
                    out.extend(found);
                }
                PinSelector::Box { min, max } => {
                    out.extend(geo.positions.iter().enumerate().filter_map(|(i, p)| {
                        (0..3)
                            .all(|k| p[k] >= min[k] && p[k] <= max[k])
                            .then_some(i as u32)
                    }));
                }
            }
        }
        out.sort_unstable();
        out.dedup();
        Ok(out)
    }
}
