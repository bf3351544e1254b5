//! The crate's modules import one another in one order, with no cycle: the test below checks every
//! source file against [`ORDER`] (`vt_check::module_order`). The crate docs (`lib.rs`) describe the
//! same order.

/// The top-level modules, each importing only modules before it.
const ORDER: [&str; 17] = [
    "device",
    "geometry",
    "host",
    "model",
    "data",
    "synthetic",
    "refine",
    "loss",
    "optim",
    "config",
    "run",
    "eval",
    "train",
    "report",
    "track",
    "bench",
    "sweep",
];

/// Files that are not part of the graph: the crate root declares the modules, the binary is a
/// crate of its own, and this file names module paths in strings.
const NOT_MODULES: [&str; 3] = ["lib.rs", "main.rs", "module_order.rs"];

#[test]
fn modules_import_only_the_modules_before_them() {
    let src = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    if let Err(wrong) = vt_check::module_order::check(&src, &ORDER, &NOT_MODULES) {
        panic!("the module order (src/module_order.rs) is broken:\n{wrong}");
    }
}
