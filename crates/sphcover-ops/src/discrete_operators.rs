//! The common interface of the operator families, so that callers (and the consistency
//! example) can swap the thesis form for a consistent one.

use glam::DVec3;

/// Discrete differential operators at support centres: scalar fields are one `f64` per
/// support, vector fields one [`DVec3`] per support. Every operator returns zero (never NaN)
/// at supports without usable neighbours.
///
/// Implementations panic when a field does not have one value per support, like slice
/// indexing; fields are otherwise used as given (NaN in, NaN out).
pub trait DiscreteOperators {
    /// Number of supports.
    fn len(&self) -> usize;
    /// True when there is no support.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// `Grad(u)`.
    fn grad(&self, u: &[f64]) -> Vec<DVec3>;
    /// `Div(v)`.
    fn div(&self, v: &[DVec3]) -> Vec<f64>;
    /// `Lap(u)`.
    fn lap(&self, u: &[f64]) -> Vec<f64>;
    /// `Curl(v)`.
    fn curl(&self, v: &[DVec3]) -> Vec<DVec3>;
    /// `Lap(v)`, component by component.
    fn lap_vector(&self, v: &[DVec3]) -> Vec<DVec3> {
        let component = |k: usize| self.lap(&v.iter().map(|x| x[k]).collect::<Vec<f64>>());
        let (x, y, z) = (component(0), component(1), component(2));
        (0..v.len()).map(|i| DVec3::new(x[i], y[i], z[i])).collect()
    }
}
