//! Skeletal sheets of thin parts from CT volumes (thesis §6).
//!
//! This crate will hold the skeleton pipeline: a quadratic cover of the intensity, the dual
//! complex tetrahedral mesh, ridge points on its edges (eq. 6.1, 6.4, 6.5), patches around
//! ridge edges, derivative smoothing, cleaning of fragments and holes, and the
//! non-maximum-suppression baseline for comparison.
//!
//! It builds on `sphcover-core`, `sphcover-ops` and `sphcover-tetra`. Nothing is implemented
//! yet, so it exposes no API.
#![deny(missing_docs)]
