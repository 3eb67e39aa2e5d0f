//! The options of a reconstruction as a person states them: the flags of `sphcover recon` and
//! the keywords of the Python `reconstruct`, checked once here and turned into
//! [`ReconParams`], so that both front ends accept the same values and refuse the others
//! with the same message.

use thiserror::Error;

use crate::graph_cut::GraphCutParams;
use crate::pipeline::{Method, ReconParams, Trim};

/// The most neighbours [`ReconOptions::normal_neighbours`] takes. Normals come from a plane
/// fit; beyond a few hundred neighbours the fit only blurs, and the neighbour lists cost
/// `n·k` memory (100,000 neighbours on 5K points took 4 GB).
pub const MAX_NORMAL_NEIGHBOURS: usize = 500;

/// The finest polygonisation depth [`ReconOptions::depth`] takes.
pub const MAX_DEPTH: u32 = 14;

/// How far from the samples the surface is kept ([`ReconOptions::trim`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum TrimOption {
    /// Keep everything: a closed surface, extrapolated where the scan is open.
    Off,
    /// Leave out what the scanner never saw, close holes ([`Trim::Unseen`]).
    #[default]
    Unseen,
    /// Three sample spacings.
    Auto,
    /// This distance, relative to the longest bounding-box edge.
    Distance(f64),
}

/// How the cover tolerance follows the scan's noise ([`ReconOptions::noise`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum NoiseOption {
    /// ε is at least 4× the measured noise (the default without a given ε).
    Auto,
    /// ε as given (the default with a given ε).
    Off,
    /// ε is at least 4× this noise σ, relative to the longest bounding-box edge.
    Value(f64),
}

/// The user-facing options of a reconstruction; `Default` gives the defaults of the command
/// line. Every `None` takes the library default of [`ReconParams`].
#[derive(Clone, Debug, PartialEq)]
pub struct ReconOptions {
    /// The pipeline.
    pub method: Method,
    /// Cover tolerance ε relative to the longest bounding-box edge, in (0, 1). A given ε is
    /// used as given unless [`ReconOptions::noise`] says otherwise.
    pub eps: Option<f64>,
    /// How ε follows the scan's noise; `None`: [`NoiseOption::Auto`] without a given ε,
    /// [`NoiseOption::Off`] with one.
    pub noise: Option<NoiseOption>,
    /// Graph-cut ratio of terminal to edge cost (both graph cuts), positive.
    pub k: Option<f64>,
    /// Trimming of surface far from the samples.
    pub trim: TrimOption,
    /// Polygonisation depth, `1..=MAX_DEPTH`.
    pub depth: Option<u32>,
    /// Diffusion: strength of the fit to the samples' normals, non-negative.
    pub normal_fit: Option<f64>,
    /// Diffusion: strength of the fit to the samples' positions, non-negative.
    pub position_fit: Option<f64>,
    /// Neighbours for the normals of unoriented input, `3..=MAX_NORMAL_NEIGHBOURS`.
    pub normal_neighbours: usize,
    /// Move the vertices onto quadrics fitted to the samples near them.
    pub refine: bool,
    /// Fill the tunnels one or two grid vertices wide through thin walls
    /// ([`ReconParams::fill_pinholes`]).
    pub fill_pinholes: bool,
    /// Seed of the random choices (cover expansion order).
    pub seed: u64,
}

impl Default for ReconOptions {
    fn default() -> Self {
        ReconOptions {
            method: Method::Integrated,
            eps: None,
            noise: None,
            k: None,
            trim: TrimOption::Unseen,
            depth: None,
            normal_fit: None,
            position_fit: None,
            normal_neighbours: ReconParams::default().normals.k,
            refine: true,
            fill_pinholes: true,
            seed: 0,
        }
    }
}

/// An option out of its range. Its message reads `<option> <value> must be <requirement>`
/// with the option's name as in [`ReconOptions`] (`normal_neighbours`); a command line
/// spells the name its own way ([`OptionError::requirement`] is the rest).
#[derive(Clone, Debug, PartialEq, Error)]
#[error("{option} {value} must be {requirement}")]
pub struct OptionError {
    /// The field of [`ReconOptions`].
    pub option: &'static str,
    /// The value given, as Rust displays it.
    pub value: String,
    /// What the value must be (`"in (0, 1)"`, `"a positive number"`).
    pub requirement: String,
}

impl OptionError {
    fn new(option: &'static str, value: impl ToString, requirement: impl Into<String>) -> Self {
        OptionError {
            option,
            value: value.to_string(),
            requirement: requirement.into(),
        }
    }
}

impl ReconOptions {
    /// The parameters of [`crate::reconstruct`] these options ask for, or the first option
    /// out of its range.
    pub fn params(&self) -> Result<ReconParams, OptionError> {
        let defaults = ReconParams::default();
        if let Some(eps) = self.eps
            && !(eps.is_finite() && eps > 0.0 && eps < 1.0)
        {
            return Err(OptionError::new("eps", eps, "in (0, 1)"));
        }
        if let Some(k) = self.k
            && !(k.is_finite() && k > 0.0)
        {
            return Err(OptionError::new("k", k, "a positive number"));
        }
        let trim = match self.trim {
            TrimOption::Off => Trim::Off,
            TrimOption::Unseen => Trim::Unseen,
            TrimOption::Auto => Trim::SampleSpacings(3.0),
            TrimOption::Distance(d) if d.is_finite() && d > 0.0 => Trim::Distance(d),
            TrimOption::Distance(d) => {
                return Err(OptionError::new("trim", d, "a positive number"));
            }
        };
        if let Some(d) = self.depth
            && !(1..=MAX_DEPTH).contains(&d)
        {
            return Err(OptionError::new("depth", d, format!("in 1..={MAX_DEPTH}")));
        }
        if !(3..=MAX_NORMAL_NEIGHBOURS).contains(&self.normal_neighbours) {
            return Err(OptionError::new(
                "normal_neighbours",
                self.normal_neighbours,
                format!("in 3..={MAX_NORMAL_NEIGHBOURS}"),
            ));
        }
        let (noise_tolerance, noise) = match (self.noise, self.eps) {
            (Some(NoiseOption::Auto), _) | (None, None) => (defaults.noise_tolerance, None),
            (Some(NoiseOption::Off), _) | (None, Some(_)) => (None, None),
            (Some(NoiseOption::Value(v)), _) if v.is_finite() && v >= 0.0 => {
                (defaults.noise_tolerance, Some(v))
            }
            (Some(NoiseOption::Value(v)), _) => {
                return Err(OptionError::new(
                    "noise",
                    v,
                    "auto, off or a non-negative number",
                ));
            }
        };
        let mut params = ReconParams {
            method: self.method,
            noise_tolerance,
            noise,
            cover: sphcover_core::SurfaceCoverParams {
                eps: self.eps.unwrap_or(defaults.cover.eps),
                seed: self.seed,
                ..defaults.cover.clone()
            },
            depth: self.depth,
            trim,
            ..defaults
        };
        params.normals.k = self.normal_neighbours;
        if !self.refine {
            params.refine = None;
        }
        params.fill_pinholes = self.fill_pinholes;
        for (name, value, slot) in [
            (
                "normal_fit",
                self.normal_fit,
                &mut params.diffusion.normal_fit,
            ),
            (
                "position_fit",
                self.position_fit,
                &mut params.diffusion.position_fit,
            ),
        ] {
            if let Some(v) = value {
                if !(v.is_finite() && v >= 0.0) {
                    return Err(OptionError::new(name, v, "a non-negative number"));
                }
                *slot = v;
            }
        }
        if let Some(k) = self.k {
            params.graph_cut = GraphCutParams {
                k,
                ..params.graph_cut
            };
            params.graph_cut_only.k = k;
        }
        Ok(params)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_defaults_are_the_library_defaults() {
        assert_eq!(ReconOptions::default().params(), Ok(ReconParams::default()));
    }

    #[test]
    fn out_of_range_options_are_named_with_their_value() {
        let bad = |options: ReconOptions| options.params().unwrap_err().to_string();
        let eps = ReconOptions {
            eps: Some(2.0),
            ..ReconOptions::default()
        };
        assert_eq!(bad(eps), "eps 2 must be in (0, 1)");
        let neighbours = ReconOptions {
            normal_neighbours: 2,
            ..ReconOptions::default()
        };
        assert_eq!(bad(neighbours), "normal_neighbours 2 must be in 3..=500");
        let fit = ReconOptions {
            position_fit: Some(-1.0),
            ..ReconOptions::default()
        };
        assert_eq!(bad(fit), "position_fit -1 must be a non-negative number");
        let trim = ReconOptions {
            trim: TrimOption::Distance(f64::NAN),
            ..ReconOptions::default()
        };
        assert_eq!(bad(trim), "trim NaN must be a positive number");
    }

    #[test]
    fn options_reach_their_parameters() {
        let params = ReconOptions {
            method: Method::GraphCut,
            k: Some(7.0),
            trim: TrimOption::Auto,
            depth: Some(5),
            refine: false,
            fill_pinholes: false,
            seed: 3,
            ..ReconOptions::default()
        }
        .params()
        .unwrap();
        assert_eq!(params.method, Method::GraphCut);
        assert_eq!((params.graph_cut.k, params.graph_cut_only.k), (7.0, 7.0));
        assert_eq!(params.trim, Trim::SampleSpacings(3.0));
        assert_eq!((params.depth, params.cover.seed), (Some(5), 3));
        assert!(params.refine.is_none());
        assert!(!params.fill_pinholes);
        assert!(ReconOptions::default().params().unwrap().fill_pinholes);
    }
}
