//! Nucleus bend plugin (work in progress).

use nucleus_sdk::prelude::*;

fn kinds() -> Vec<KindSpec> {
    Vec::new()
}

nucleus_sdk::export_plugin!(PluginDef {
    name: "bend",
    version: env!("CARGO_PKG_VERSION"),
    kinds,
});
