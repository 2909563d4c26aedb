//! Nucleus air plugin (work in progress).

use nucleus_sdk::prelude::*;

fn kinds() -> Vec<KindSpec> {
    Vec::new()
}

nucleus_sdk::export_plugin!(PluginDef {
    name: "air",
    version: env!("CARGO_PKG_VERSION"),
    kinds,
});
