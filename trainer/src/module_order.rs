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

#[test]
fn modules_import_only_the_modules_before_them() {
    vt_check::module_order::assert_crate_order(env!("CARGO_MANIFEST_DIR"), &ORDER);
}
