//! The plain Rust side of a plugin: the [`ConstraintGroup`] trait an author implements, the
//! [`KindSpec`] that describes a kind, and the adapter that turns both into the ABI types with
//! every call guarded against panics.

use std::panic::{catch_unwind, AssertUnwindSafe};

use abi_stable::{
    sabi_trait::TD_Opaque,
    std_types::{RResult, RStr, RString, RVec},
};

use crate::abi::{
    GroupAbi, GroupAbi_TO, GroupBox, KindInfo, ParamInfo, PluginError, PluginInfo, Residual,
    SceneView, SolveContext, Stages, Stat, SDK_ABI_VERSION,
};
use crate::params::ParamSpec;

/// A constraint group: ALL the constraints of one kind in a scene, as one batch.
///
/// The core calls, per substep of length `h`:
///
/// 1. [`force`](Self::force) — velocity level, before prediction (`v += h·f/m`);
/// 2. prediction by the core (`x0 = x; x = x0 + h·v`);
/// 3. [`begin_substep`](Self::begin_substep) — reset XPBD multipliers, refit a BVH;
/// 4. [`project`](Self::project), `importance` times, interleaved with the other groups;
/// 5. velocity update by the core (`v = (x − x0)/h`);
/// 6. [`end_substep`](Self::end_substep) — velocity level: restitution, friction, damping.
///
/// Only the stages listed by [`stages`](Self::stages) are ever called, so an unused stage
/// costs nothing. [`residual`](Self::residual) and [`report`](Self::report) are called once
/// per frame for the stats.
pub trait ConstraintGroup: Send + 'static {
    /// The stages this group implements (`Stages::PROJECT | Stages::FORCE`, ...).
    fn stages(&self) -> Stages;

    /// Number of constraints in the group (0: the core never schedules it).
    fn len(&self) -> usize;

    /// Whether the group has no constraints.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Velocity-level forces before prediction.
    fn force(&mut self, _ctx: &mut SolveContext<'_>) -> Result<(), PluginError> {
        Ok(())
    }

    /// Start of a substep, after prediction.
    fn begin_substep(&mut self, _ctx: &mut SolveContext<'_>) -> Result<(), PluginError> {
        Ok(())
    }

    /// One Gauss-Seidel pass over every constraint of the group.
    fn project(&mut self, _ctx: &mut SolveContext<'_>) -> Result<(), PluginError> {
        Ok(())
    }

    /// End of a substep, after the velocity update.
    fn end_substep(&mut self, _ctx: &mut SolveContext<'_>) -> Result<(), PluginError> {
        Ok(())
    }

    /// How far the constraints are from satisfied at the current positions.
    fn residual(&self, ctx: &SolveContext<'_>) -> Residual;

    /// Named values for the stats (once per frame).
    fn report(&self, _ctx: &SolveContext<'_>, _out: &mut Vec<(String, f64)>) {}
}

/// Builds a group from the kind's parameters (JSON text, already validated and completed
/// with defaults by the host) and the scene.
pub type Factory =
    fn(params_json: &str, scene: &SceneView<'_>) -> Result<Box<dyn ConstraintGroup>, PluginError>;

/// Everything about one constraint kind.
pub struct KindSpec {
    /// Name as written in scenes; unique across all loaded plugins.
    pub name: &'static str,
    /// What the kind does.
    pub doc: &'static str,
    /// Default order.
    pub default_order: i32,
    /// Default importance.
    pub default_importance: u32,
    /// Unit of the residual.
    pub residual_unit: &'static str,
    /// Parameters.
    pub params: Vec<ParamSpec>,
    /// The factory.
    pub factory: Factory,
}

impl KindSpec {
    /// The ABI description.
    pub fn info(&self) -> KindInfo {
        KindInfo {
            name: self.name.into(),
            doc: self.doc.into(),
            default_order: self.default_order,
            default_importance: self.default_importance,
            residual_unit: self.residual_unit.into(),
            params: self.params.iter().map(ParamSpec::info).collect(),
        }
    }

    /// The ABI parameter descriptions.
    pub fn param_infos(&self) -> Vec<ParamInfo> {
        self.params.iter().map(ParamSpec::info).collect()
    }
}

/// A whole plugin: what [`export_plugin!`](crate::export_plugin) exports.
pub struct PluginDef {
    /// Plugin name.
    pub name: &'static str,
    /// Plugin version.
    pub version: &'static str,
    /// Its kinds.
    pub kinds: fn() -> Vec<KindSpec>,
}

impl PluginDef {
    /// The ABI description of the plugin.
    pub fn info(&self) -> PluginInfo {
        PluginInfo {
            name: self.name.into(),
            version: self.version.into(),
            sdk_abi_version: SDK_ABI_VERSION,
            kinds: (self.kinds)().iter().map(KindSpec::info).collect(),
        }
    }

    /// Builds a group in-process, through the same validation and adapter the ABI uses.
    pub fn create_group(
        &self,
        kind: &str,
        params_json: &str,
        scene: &SceneView<'_>,
    ) -> Result<GroupBox, PluginError> {
        let kinds = (self.kinds)();
        let spec = kinds.iter().find(|k| k.name == kind).ok_or_else(|| {
            PluginError::new(
                PluginError::UNKNOWN_KIND,
                kind,
                format!("plugin `{}` does not provide this kind", self.name),
            )
        })?;
        let params = crate::params::validate_json(params_json, &spec.param_infos())?;
        let group = (spec.factory)(&params, scene)?;
        Ok(adapt(group))
    }
}

/// The message of a panic payload.
pub fn panic_message(payload: &(dyn std::any::Any + Send)) -> String {
    if let Some(s) = payload.downcast_ref::<&str>() {
        (*s).to_string()
    } else if let Some(s) = payload.downcast_ref::<String>() {
        s.clone()
    } else {
        "a panic with a non-string payload".to_string()
    }
}

thread_local! {
    /// Depth of nested [`guard`] calls on this thread, and where the last guarded panic was.
    static GUARD: std::cell::RefCell<(u32, Option<String>)> = const { std::cell::RefCell::new((0, None)) };
}

/// Installs (once per library) a panic hook that, inside [`guard`], records where the panic
/// happened instead of printing it: the host reports it as an error naming the plugin and
/// group. Outside a guard the previous hook runs as usual.
fn install_quiet_hook() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            let guarded = GUARD
                .try_with(|g| {
                    let mut g = g.borrow_mut();
                    if g.0 > 0 {
                        g.1 = info
                            .location()
                            .map(|l| format!("{}:{}", l.file(), l.line()));
                        true
                    } else {
                        false
                    }
                })
                .unwrap_or(false);
            if !guarded {
                previous(info);
            }
        }));
    });
}

/// Runs `f`, turning a panic into [`PluginError::PANICKED`] whose message says where the
/// plugin panicked.
pub fn guard<T>(f: impl FnOnce() -> Result<T, PluginError>) -> RResult<T, PluginError> {
    install_quiet_hook();
    let _ = GUARD.try_with(|g| g.borrow_mut().0 += 1);
    let result = catch_unwind(AssertUnwindSafe(f));
    let location = GUARD
        .try_with(|g| {
            let mut g = g.borrow_mut();
            g.0 -= 1;
            g.1.take()
        })
        .ok()
        .flatten();
    match result {
        Ok(Ok(v)) => RResult::ROk(v),
        Ok(Err(e)) => RResult::RErr(e),
        Err(payload) => {
            let msg = panic_message(payload.as_ref());
            let msg = match location {
                Some(at) => format!("panicked at {at}: {msg}"),
                None => format!("panicked: {msg}"),
            };
            RResult::RErr(PluginError::new(PluginError::PANICKED, "", msg))
        }
    }
}

/// Wraps an author's group into the ABI trait object.
pub fn adapt(group: Box<dyn ConstraintGroup>) -> GroupBox {
    GroupAbi_TO::from_value(
        Adapter {
            group,
            poisoned: false,
        },
        TD_Opaque,
    )
}

/// Guards every call of a group: a panic becomes an error and poisons the group, so it is
/// never called again in a possibly broken state.
struct Adapter {
    group: Box<dyn ConstraintGroup>,
    poisoned: bool,
}

impl Adapter {
    fn call(
        &mut self,
        f: impl FnOnce(&mut dyn ConstraintGroup) -> Result<(), PluginError>,
    ) -> RResult<(), PluginError> {
        if self.poisoned {
            return RResult::RErr(poisoned());
        }
        let group = &mut *self.group;
        let result = guard(|| f(group));
        if matches!(&result, RResult::RErr(e) if e.code == PluginError::PANICKED) {
            self.poisoned = true;
        }
        result
    }
}

fn poisoned() -> PluginError {
    PluginError::new(
        PluginError::PANICKED,
        "",
        "the group panicked earlier and is poisoned",
    )
}

impl GroupAbi for Adapter {
    fn stages(&self) -> Stages {
        match catch_unwind(AssertUnwindSafe(|| self.group.stages())) {
            Ok(s) => s,
            Err(_) => Stages::NONE,
        }
    }

    fn constraint_count(&self) -> u64 {
        catch_unwind(AssertUnwindSafe(|| self.group.len() as u64)).unwrap_or(0)
    }

    fn force(&mut self, ctx: &mut SolveContext<'_>) -> RResult<(), PluginError> {
        self.call(|g| g.force(ctx))
    }

    fn begin_substep(&mut self, ctx: &mut SolveContext<'_>) -> RResult<(), PluginError> {
        self.call(|g| g.begin_substep(ctx))
    }

    fn project(&mut self, ctx: &mut SolveContext<'_>) -> RResult<(), PluginError> {
        self.call(|g| g.project(ctx))
    }

    fn end_substep(&mut self, ctx: &mut SolveContext<'_>) -> RResult<(), PluginError> {
        self.call(|g| g.end_substep(ctx))
    }

    fn residual(&self, ctx: &SolveContext<'_>) -> RResult<Residual, PluginError> {
        if self.poisoned {
            return RResult::RErr(poisoned());
        }
        guard(|| Ok(self.group.residual(ctx)))
    }

    fn report(&self, ctx: &SolveContext<'_>) -> RResult<RVec<Stat>, PluginError> {
        if self.poisoned {
            return RResult::RErr(poisoned());
        }
        guard(|| {
            let mut out = Vec::new();
            self.group.report(ctx, &mut out);
            Ok(out
                .into_iter()
                .map(|(name, value)| Stat {
                    name: RString::from(name),
                    value,
                })
                .collect())
        })
    }
}

/// The `describe` entry point of an exported plugin (used by [`export_plugin!`](crate::export_plugin)).
#[doc(hidden)]
pub fn describe_entry(def: &PluginDef) -> RResult<PluginInfo, PluginError> {
    guard(|| Ok(def.info()))
}

/// The `create_group` entry point of an exported plugin (used by [`export_plugin!`](crate::export_plugin)).
#[doc(hidden)]
pub fn create_entry(
    def: &PluginDef,
    kind: RStr<'_>,
    params_json: RStr<'_>,
    scene: &SceneView<'_>,
) -> RResult<GroupBox, PluginError> {
    guard(|| def.create_group(kind.as_str(), params_json.as_str(), scene))
}
