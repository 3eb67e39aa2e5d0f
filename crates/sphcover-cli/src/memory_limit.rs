//! The memory limit of a run's readers ([`ReadOptions::max_bytes`]): `--max-memory` where
//! the command has it, else a share of the memory this process may use, so that a file
//! declaring more data than the machine holds (a decompression bomb, a lying header) is
//! refused from its header with its name and sizes instead of ending the process in a
//! failed allocation.
//!
//! The default is [`READ_LIMIT_PERCENT`]% of the memory this process may use
//! ([`process_memory`]).

use sphcover_core::io::{IoError, ReadOptions};
use sphcover_core::{ProcessMemory, READ_LIMIT_PERCENT, process_memory};

use crate::exit::BadInput;

/// The limit of a run's readers and where it came from.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MemoryLimit {
    bytes: Option<u64>,
    origin: Origin,
}

#[derive(Clone, Debug, PartialEq, Eq)]
enum Origin {
    /// `--max-memory`.
    Flag,
    /// [`READ_LIMIT_PERCENT`] of the process's memory; `flag` says whether the command has a
    /// `--max-memory` that would set it instead.
    Default { memory: ProcessMemory, flag: bool },
    /// Nothing to derive a default from.
    Unknown,
}

impl MemoryLimit {
    /// The limit of a command with `--max-memory`: the flag's value, else the default.
    pub fn from_flag(max_memory: Option<u64>) -> MemoryLimit {
        match max_memory {
            Some(bytes) => MemoryLimit {
                bytes: Some(bytes),
                origin: Origin::Flag,
            },
            None => MemoryLimit::default_with(process_memory(), true),
        }
    }

    /// The limit of a command without `--max-memory`: the default.
    pub fn machine_default() -> MemoryLimit {
        MemoryLimit::default_with(process_memory(), false)
    }

    fn default_with(memory: Option<ProcessMemory>, flag: bool) -> MemoryLimit {
        match memory {
            Some(memory) => MemoryLimit {
                bytes: Some(memory.read_limit()),
                origin: Origin::Default { memory, flag },
            },
            None => MemoryLimit {
                bytes: None,
                origin: Origin::Unknown,
            },
        }
    }

    /// The limit in bytes; `None` when the machine's memory is unknown and no flag set it.
    pub fn bytes(&self) -> Option<u64> {
        self.bytes
    }

    /// `options` with this limit.
    pub fn apply(&self, options: ReadOptions) -> ReadOptions {
        ReadOptions {
            max_bytes: self.bytes,
            ..options
        }
    }

    /// Where the limit came from, for messages: `--max-memory`, `60% of this machine's
    /// 23.5 GiB`, …
    pub fn origin(&self) -> String {
        match &self.origin {
            Origin::Flag => "--max-memory".to_owned(),
            Origin::Default { memory, flag } => {
                let hint = if *flag { "; --max-memory sets it" } else { "" };
                format!("{READ_LIMIT_PERCENT}% of {}{hint}", memory.describe())
            }
            Origin::Unknown => "none: the machine's memory is unknown".to_owned(),
        }
    }

    /// A reader's error for the command: a refusal over the limit says where the limit came
    /// from, a refusal of non-finite values names the flag that drops them (both stay bad
    /// input, exit 2); every other error is passed on unchanged.
    pub fn explain(&self, error: IoError) -> anyhow::Error {
        match error {
            IoError::OverMemoryLimit { .. } => {
                BadInput(format!("{error} ({})", self.origin())).into()
            }
            IoError::NonFinite { .. } => {
                BadInput(format!("{error}; --drop-non-finite drops them")).into()
            }
            IoError::NonFiniteVoxels { all: false, .. } => {
                BadInput(format!("{error}; --drop-non-finite makes them background")).into()
            }
            other => other.into(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use sphcover_core::MemorySource;

    #[test]
    fn the_default_is_a_share_of_the_smallest_bound_and_says_so() {
        let memory = ProcessMemory {
            bytes: 10 << 30,
            source: MemorySource::AddressSpace,
        };
        let limit = MemoryLimit::default_with(Some(memory), false);
        let bytes = |limit: &MemoryLimit| limit.apply(ReadOptions::default()).max_bytes;
        assert_eq!(bytes(&limit), Some((10 << 30) / 100 * READ_LIMIT_PERCENT));
        assert_eq!(
            limit.origin(),
            "60% of the 10.0 GiB address-space limit (ulimit -v)"
        );
        let with_flag = MemoryLimit::default_with(
            Some(ProcessMemory {
                source: MemorySource::Machine,
                ..memory
            }),
            true,
        );
        assert_eq!(
            with_flag.origin(),
            "60% of this machine's 10.0 GiB; --max-memory sets it"
        );
        assert_eq!(bytes(&MemoryLimit::default_with(None, true)), None);
        let flag = MemoryLimit::from_flag(Some(1 << 30));
        assert_eq!(bytes(&flag), Some(1 << 30));
        assert_eq!(flag.origin(), "--max-memory");
    }
}
