//! End-to-end benchmark harness for `sphcover`.
//!
//! It will generate the standard synthetic scans from ground-truth meshes, run
//! `sphcover recon` and, when given, peer tools on the same input, and print time, peak memory
//! and accuracy side by side. The per-function criterion benchmarks live next to each crate
//! (`cargo bench -p sphcover-core`); this member holds the whole-pipeline harness once the
//! pipelines exist.
#![deny(missing_docs)]
