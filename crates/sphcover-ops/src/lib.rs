//! Discrete differential operators on a spherical cover (thesis §4).
//!
//! This crate will hold the pair geometry of neighbouring supports (`l`, `ρ²`, `D`, `A`, `S`,
//! `φ`, `m`; thesis eq. 4.33–4.36), the thesis operators `Grad`, `Div`, `Lap` at support
//! centres (eq. 4.21–4.29), a `Curl` by the same Stokes construction, their CSR assembly,
//! consistent variants that are exact on linear and quadratic fields, and a preconditioned
//! conjugate-gradient solver for the symmetric systems `Lap = M⁻¹(W − diag(W·1))` gives.
//!
//! It depends only on `sphcover-core`. Nothing is implemented yet: the operators are the
//! subject of their own piece of work, and this crate exposes no API until then.
#![deny(missing_docs)]
