//! One module per subcommand.

pub mod cover;
pub mod info;
pub mod recon;
pub mod skeleton;
pub mod tetra;
pub mod unavailable;
