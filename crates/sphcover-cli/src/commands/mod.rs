//! One module per subcommand.

pub mod info;
pub mod tetra;
pub mod unavailable;
