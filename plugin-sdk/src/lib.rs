//! # The Nucleus plugin SDK
//!
//! The only crate a Nucleus constraint plugin depends on. A plugin is a `cdylib` (+ `rlib`, so
//! it can be unit-tested in-process) that provides one or more constraint **kinds**. For each
//! kind used by a scene the host calls the kind's factory once, which returns a
//! **constraint group** owning *all* constraints of that kind in the scene. Every call across
//! the boundary is per group, never per constraint.
//!
//! ```ignore
//! use nucleus_sdk::prelude::*;
//!
//! struct Mine { /* SoA batch */ }
//! impl ConstraintGroup for Mine { /* stages, len, project, residual */ }
//!
//! fn kinds() -> Vec<KindSpec> { vec![KindSpec { name: "mine", /* ... */ factory: build }] }
//! nucleus_sdk::export_plugin!(PluginDef { name: "mine", version: env!("CARGO_PKG_VERSION"), kinds });
//! ```
//!
//! ## Lifecycle of a group
//!
//! Per substep of length `h`, the core runs: `force` (velocity level) → prediction
//! (`x0 = x; x = x0 + h v`) → `begin_substep` → the interleaved schedule of `project` calls
//! (each group `importance` times, ordered by `order`) → velocity update (`v = (x − x0)/h`) →
//! `end_substep` (velocity level). Once per frame: `residual` and `report`. Only the stages a
//! group lists in [`ConstraintGroup::stages`] are called.
//!
//! ## What a group may do with the particle slices
//!
//! * `project` moves `x` only, and never moves a particle whose inverse mass is 0.
//! * `force` and `end_substep` change `v` only.
//! * Nothing may write NaN or infinity: the host checks after each call and stops the run
//!   naming the plugin and the group.
//! * A group may split a call over the host's thread team, `ctx.team` ([`team`]: one call
//!   across the boundary per job), and should start no threads of its own; its result must
//!   not depend on the thread count (colour the constraints; never accumulate floats in a
//!   thread-dependent order).
//!
//! ## Versioning
//!
//! Two checks guard the boundary when a library is loaded:
//!
//! 1. abi_stable's layout check over the whole type graph of [`PluginMod`] (a prefix type).
//! 2. The SDK's own handshake: [`PluginMod::sdk_abi_version`] must equal the host's
//!    [`SDK_ABI_VERSION`].
//!
//! The rule for changing the SDK:
//!
//! * **Compatible** (no version bump): adding kinds to a plugin; adding parameters to a kind
//!   (defaults keep old scenes valid); adding new named [`Attribute`]s to the context or the
//!   scene view; adding new `PluginError` codes or `Stages` bits that old plugins never set;
//!   changing anything behind the plain Rust API ([`ConstraintGroup`], [`KindSpec`], helpers)
//!   that does not touch a `#[repr(C)]` type.
//! * **Newer plugin, older host**: a field appended to the root module *after*
//!   `create_group` (its `last_prefix_field`) or a method appended to [`GroupAbi`] after
//!   `report` is accepted by abi_stable; the older host simply never uses it.
//! * **Older plugin, newer host**: refused by abi_stable's layout check once the root module or
//!   the group trait has grown, so new fields are added only together with a bump.
//! * **Breaking** (bump [`SDK_ABI_VERSION`] and the major of [`ROOT_MODULE_VERSION`]): any
//!   change to the layout of a `#[repr(C)]` type in [`abi`] (a field added to
//!   [`SolveContext`], [`SceneView`], [`ObjectView`], ...), or a change of meaning of an
//!   existing field or call. The host then refuses older plugins with a clear message; they
//!   must be rebuilt.
//!
//! So the root module and the context stay small and frozen; growth happens through new kinds,
//! new parameters and new named attributes.

#![warn(missing_docs)]

pub mod abi;
pub mod colour;
pub mod group;
pub mod lanes;
pub mod params;
pub mod stage;
pub mod team;
pub mod testing;
pub mod view;
pub mod xpbd;

pub use abi::*;
pub use group::{adapt, guard, ConstraintGroup, Factory, KindSpec, PluginDef};
pub use params::ParamSpec;
pub use stage::Stage;
pub use team::{SharedArray, TeamRef};
pub use view::Particles;

#[doc(hidden)]
pub use abi_stable;
pub use glam;
pub use serde;
pub use serde_json;

/// Everything a plugin usually needs.
pub mod prelude {
    pub use crate::abi::{
        ObjectView, PluginError, Residual, SceneView, SolveContext, Stages, FLAG_KINEMATIC,
    };
    pub use crate::group::{ConstraintGroup, KindSpec, PluginDef};
    pub use crate::params::{self, ParamSpec};
    pub use crate::view::Particles;
    pub use crate::xpbd;
    pub use glam::DVec3;
}

/// The exported symbol abi_stable looks up (`abi_stable::library::ROOT_MODULE_LOADER_NAME`),
/// spelt out because `#[export_name]` needs a literal; a unit test keeps the two equal.
#[doc(hidden)]
#[macro_export]
macro_rules! __root_module_loader_name {
    () => {
        "_1as_0lib_1header_0root_bmodule_bloader"
    };
}

/// Exports a plugin: `export_plugin!(PluginDef { name, version, kinds })`.
///
/// Defines `pub fn nucleus_plugin() -> &'static PluginDef` for in-process use (unit tests)
/// and the root module the host loads from the `cdylib`. Use it once per plugin crate.
///
/// Every plugin exports the same symbol, so two plugins cannot be linked into one binary as
/// rlibs. To test several plugins in-process together, give each plugin crate a feature
/// `no-export = []` and depend on them with `features = ["no-export"]`: the root module is
/// then left out of the rlib (the `cdylib` built by `cargo build` keeps it, since
/// dev-dependency features are not unified into plain builds).
#[macro_export]
macro_rules! export_plugin {
    ($def:expr) => {
        /// This plugin's definition, for in-process use exactly as the host uses it.
        pub fn nucleus_plugin() -> &'static $crate::PluginDef {
            static DEF: $crate::PluginDef = $def;
            &DEF
        }

        #[doc(hidden)]
        #[allow(unexpected_cfgs)]
        pub mod __nucleus_plugin_export_gate {
            #[cfg(not(feature = "no-export"))]
            pub mod __nucleus_plugin_export {
                use $crate::abi_stable::prefix_type::PrefixTypeTrait as _;

                extern "C" fn describe(
                ) -> $crate::abi_stable::std_types::RResult<$crate::PluginInfo, $crate::PluginError>
                {
                    $crate::group::describe_entry(super::super::nucleus_plugin())
                }

                extern "C" fn create_group(
                    kind: $crate::abi_stable::std_types::RStr<'_>,
                    params_json: $crate::abi_stable::std_types::RStr<'_>,
                    scene: &$crate::SceneView<'_>,
                ) -> $crate::abi_stable::std_types::RResult<$crate::GroupBox, $crate::PluginError>
                {
                    $crate::group::create_entry(
                        super::super::nucleus_plugin(),
                        kind,
                        params_json,
                        scene,
                    )
                }

                fn root_module() -> $crate::PluginModRef {
                    $crate::PluginMod {
                        sdk_abi_version: $crate::SDK_ABI_VERSION,
                        describe,
                        create_group,
                    }
                    .leak_into_prefix()
                }

                extern "C" fn erased_root_module() -> $crate::abi_stable::library::RootModuleResult
                {
                    $crate::abi_stable::library::__call_root_module_loader(root_module)
                }

                /// The library header abi_stable reads when the host loads this file.
                #[export_name = $crate::__root_module_loader_name!()]
                pub static NUCLEUS_ROOT_MODULE_LOADER: $crate::abi_stable::library::LibHeader =
                    // SAFETY: `erased_root_module` returns the prefix reference of a
                    // `PluginModRef`, the module type given here, as `from_constructor` requires.
                    unsafe {
                        $crate::abi_stable::library::LibHeader::from_constructor::<
                            $crate::PluginModRef,
                        >(
                            erased_root_module,
                            $crate::abi_stable::library::CheckTypeLayout::Yes,
                        )
                    };
            }
        }
    };
}

#[cfg(test)]
mod tests {
    #[test]
    fn exported_symbol_name_matches_abi_stable() {
        assert_eq!(
            crate::__root_module_loader_name!(),
            abi_stable::library::ROOT_MODULE_LOADER_NAME
        );
    }
}
