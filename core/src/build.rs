//! From a scene to a simulation: each object's geometry becomes a simplicial complex and a run
//! of particles; each `[[constraints]]` entry becomes a group, built by the plugin providing
//! its kind from its parameters (checked against the kind's declared parameters and turned
//! into JSON); then the schedule is laid out. Every error names the scene file and line.

use abi_stable::std_types::RSlice;
use nucleus_sdk::team;
use nucleus_sdk::{Attribute, KindInfo, ObjectView, SceneView, Stage, FLAG_KINEMATIC};

use crate::complex::Complex;
use crate::error::{BuildError, PluginLoadError};
use crate::object::{MovingPins, ObjectData};
use crate::particles::Particles;
use crate::plugins::Registry;
use crate::scene::{ConstraintSpec, Scene, SolverSettings};
use crate::simulation::{Group, Simulation};

/// The most `project` calls one substep may make (iterations × the groups' importances). The
/// schedule is laid out as a list of calls, so a scene asking for billions would exhaust memory
/// before its first step; a million calls a substep is already seconds a substep.
pub const MAX_CALLS_PER_SUBSTEP: u64 = 1 << 20;

impl Simulation {
    /// Builds the simulation: geometry, particles, and one group per constraint entry through
    /// the plugin providing its kind.
    pub fn build(scene: &Scene, registry: &Registry) -> Result<Simulation, BuildError> {
        let settings = scene.file.solver.clone();
        let (objects, particles) = objects_and_particles(scene)?;
        let pins = MovingPins::new(&objects, &particles);
        let groups = groups(scene, registry, &settings, &objects, &particles)?;
        check_call_count(scene, &settings, &groups)?;
        let mut sim = Simulation {
            settings,
            objects,
            particles,
            groups,
            calls: Vec::new(),
            force_groups: Vec::new(),
            begin_groups: Vec::new(),
            end_groups: Vec::new(),
            pins,
            time: 0.0,
            frame: 0,
            threads: team::configured_threads(),
        };
        sim.reschedule();
        Ok(sim)
    }

    /// Parses scene text (as `inline.toml`) and builds it: a shortcut for tests.
    pub fn from_toml(text: &str, registry: &Registry) -> Result<Simulation, BuildError> {
        let scene = Scene::parse(text, std::path::Path::new("inline.toml"))?;
        Self::build(&scene, registry)
    }
}

/// Every object of the scene, in order, and its particles: pinned ones kinematic (inverse mass
/// 0, at rest), the others with the object's initial velocity.
fn objects_and_particles(scene: &Scene) -> Result<(Vec<ObjectData>, Particles), BuildError> {
    let mut objects = Vec::new();
    let mut p = Particles::default();
    for (oi, spec) in scene.file.objects.iter().enumerate() {
        let geo = scene.geometry(spec)?;
        let name = spec.name.get_ref();
        let complex = Complex::build(
            geo.positions.len(),
            &geo.points,
            &geo.edges,
            &geo.triangles,
            &geo.tets,
        )
        .map_err(|e| scene.invalid(spec.name.span(), format!("object `{name}`: {e}")))?;
        let pins = scene.pins(spec, &geo)?;
        let masses = scene.masses(spec, &geo)?;
        let first = p.x.len() as u32;
        let mut data = ObjectData::from_complex(name, first, &complex);
        data.pin_motion = spec.pin_motion.clone();
        data.sequence = geo.sequence.clone();
        objects.push(data);
        for (i, (pos, m)) in geo.positions.iter().zip(&masses).enumerate() {
            let pinned = pins.binary_search(&(i as u32)).is_ok();
            p.x.push(*pos);
            p.x0.push(*pos);
            p.rest.push(*pos);
            p.v.push(if pinned { [0.0; 3] } else { spec.velocity });
            p.mass.push(*m);
            p.inv_mass.push(if pinned { 0.0 } else { 1.0 / m });
            p.object.push(oi as u32);
            p.flags.push(if pinned { FLAG_KINEMATIC } else { 0 });
        }
    }
    Ok((objects, p))
}

/// One group per `[[constraints]]` entry, in scene order, each built by its kind's plugin and
/// named after its kind (`kind`, `kind#2`, ...) unless the scene names it.
fn groups(
    scene: &Scene,
    registry: &Registry,
    settings: &SolverSettings,
    objects: &[ObjectData],
    p: &Particles,
) -> Result<Vec<Group>, BuildError> {
    let views: Vec<ObjectView<'_>> = objects.iter().map(ObjectData::view).collect();
    let mut groups = Vec::new();
    let mut kind_counts: std::collections::BTreeMap<String, u32> = Default::default();
    for c in &scene.file.constraints {
        let kind = c.kind.get_ref();
        let location = scene.location(c.kind.span().start);
        let (plugin, info) = registry.find(kind).map_err(|error| BuildError::Plugin {
            location: location.clone(),
            error: Box::new(error),
        })?;
        let n = kind_counts.entry(kind.clone()).or_insert(0);
        *n += 1;
        let name = c.name.clone().unwrap_or_else(|| {
            if *n == 1 {
                kind.clone()
            } else {
                format!("{kind}#{n}")
            }
        });
        let targets: Vec<u32> = match &c.objects {
            Some(list) => list
                .iter()
                .filter_map(|o| objects.iter().position(|d| &d.name == o.get_ref()))
                .map(|i| i as u32)
                .collect(),
            None => (0..objects.len() as u32).collect(),
        };
        let json = params_json(scene, c, &name, info)?;
        let view = SceneView {
            objects: RSlice::from_slice(&views),
            targets: RSlice::from_slice(&targets),
            rest: RSlice::from_slice(&p.rest),
            inv_mass: RSlice::from_slice(&p.inv_mass),
            attributes: RSlice::from_slice(&[] as &[Attribute<'_>]),
            gravity: settings.gravity,
            frame_dt: 1.0 / settings.frame_rate,
            substeps: settings.substeps,
        };
        let group = plugin.create_group(kind, &json, &view).map_err(|error| {
            let plugin_error = PluginLoadError::Factory {
                plugin: plugin.info.name.to_string(),
                path: plugin.path.clone(),
                group: name.clone(),
                error: Box::new(error),
            };
            BuildError::Plugin {
                location: location.clone(),
                error: Box::new(plugin_error),
            }
        })?;
        let stages = group.stages();
        let len = group.constraint_count();
        groups.push(Group {
            name,
            kind: kind.clone(),
            plugin: plugin.info.name.to_string(),
            path: plugin.path.clone(),
            group,
            stages,
            order: c.order.unwrap_or(info.default_order),
            importance: c.importance.unwrap_or(info.default_importance),
            len,
            residual_unit: info.residual_unit.to_string(),
        });
    }
    Ok(groups)
}

/// The parameters of constraint entry `c` (group `name`) as the JSON text its plugin's factory
/// reads: checked against the kind's declared parameters and completed with their defaults.
fn params_json(
    scene: &Scene,
    c: &ConstraintSpec,
    name: &str,
    info: &KindInfo,
) -> Result<String, BuildError> {
    let kind = c.kind.get_ref();
    let params = toml_to_json(&toml::Value::Table(
        c.params
            .as_ref()
            .map(|p| p.get_ref().clone())
            .unwrap_or_default(),
    ));
    let params_span = c.params.as_ref().map_or(c.kind.span(), |p| p.span());
    // JSON has no NaN or infinity: such a value would reach the plugin as `null`.
    if let Some((key, x)) = c.params.as_ref().and_then(|p| non_finite(p.get_ref())) {
        return Err(scene
            .invalid(
                params_span,
                format!(
                    "constraint `{name}` (kind `{kind}`): parameter `{key}` is {x}; \
                     every number must be finite"
                ),
            )
            .into());
    }
    let validated =
        nucleus_sdk::params::validate(&params, info.params.as_slice()).map_err(|e| {
            scene.invalid(
                params_span.clone(),
                format!("constraint `{name}` (kind `{kind}`): {e}"),
            )
        })?;
    Ok(serde_json::Value::Object(validated).to_string())
}

/// An error unless one substep's `project` calls fit in [`MAX_CALLS_PER_SUBSTEP`].
fn check_call_count(
    scene: &Scene,
    settings: &SolverSettings,
    groups: &[Group],
) -> Result<(), BuildError> {
    let calls: u64 = groups
        .iter()
        .filter(|g| g.runs(Stage::Project))
        .map(|g| u64::from(g.importance) * u64::from(settings.iterations))
        .sum();
    if calls <= MAX_CALLS_PER_SUBSTEP {
        return Ok(());
    }
    // Point at what made it large: the iterations, or else an importance override.
    let needle = if settings.iterations > 1 {
        "iterations"
    } else {
        "importance"
    };
    Err(scene
        .invalid_near(
            needle,
            format!(
                "{calls} projection calls per substep (iterations {} × the groups' \
                 importances) is more than the {MAX_CALLS_PER_SUBSTEP} the scheduler \
                 lays out; use fewer iterations or a lower importance",
                settings.iterations
            ),
        )
        .into())
}

/// The first parameter (by name, in key order) holding a NaN or an infinity, anywhere in its
/// value, and that number.
fn non_finite(table: &toml::Table) -> Option<(String, f64)> {
    fn find(v: &toml::Value) -> Option<f64> {
        match v {
            toml::Value::Float(f) if !f.is_finite() => Some(*f),
            toml::Value::Array(a) => a.iter().find_map(find),
            toml::Value::Table(t) => t.values().find_map(find),
            _ => None,
        }
    }
    table
        .iter()
        .find_map(|(k, v)| find(v).map(|x| (k.clone(), x)))
}

/// A TOML value as JSON (a non-finite float becomes `null`; [`non_finite`] refuses those
/// first).
fn toml_to_json(v: &toml::Value) -> serde_json::Value {
    match v {
        toml::Value::String(s) => serde_json::Value::from(s.as_str()),
        toml::Value::Integer(i) => serde_json::Value::from(*i),
        toml::Value::Float(f) => serde_json::Number::from_f64(*f)
            .map_or(serde_json::Value::Null, serde_json::Value::Number),
        toml::Value::Boolean(b) => serde_json::Value::from(*b),
        toml::Value::Datetime(d) => serde_json::Value::from(d.to_string()),
        toml::Value::Array(a) => serde_json::Value::Array(a.iter().map(toml_to_json).collect()),
        toml::Value::Table(t) => serde_json::Value::Object(
            t.iter()
                .map(|(k, v)| (k.clone(), toml_to_json(v)))
                .collect(),
        ),
    }
}
