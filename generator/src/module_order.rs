//! The generator's modules import one another in the order data flows (ARCHITECTURE.md): the test
//! below checks every source file against [`ORDER`] (`vt_check::module_order`).

/// The top-level modules, each importing only modules before it.
const ORDER: [&str; 12] =
    ["cpu_clock", "config", "plan", "assets", "scene", "physics", "render", "sensors", "annotate", "sample", "output", "cli"];

#[test]
fn modules_import_only_the_modules_before_them() {
    vt_check::module_order::assert_crate_order(env!("CARGO_MANIFEST_DIR"), &ORDER);
}
