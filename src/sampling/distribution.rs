/// A piecewise-constant 1D distribution over `n` equal cells of [0, 1) (or, read discretely, over
/// `n` items), proportional to non-negative weights.
#[derive(Clone, Debug)]
pub struct Distribution1D {
    /// Weights as given.
    pub func: Vec<f32>,
    /// Normalised CDF, `n + 1` entries from 0 to 1.
    pub cdf: Vec<f64>,
    /// Sum of weights / n (the integral of the step function over [0,1)).
    pub func_integral: f64,
}

/// A piecewise-constant 2D distribution over [0,1)²: a marginal over rows and one conditional per
/// row.
#[derive(Clone, Debug)]
pub struct Distribution2D {
    pub conditionals: Vec<Distribution1D>,
    pub marginal: Distribution1D,
}

// INTERFACE (implementation owned by the sampling work):
impl Distribution1D {
    /// Builds from non-negative finite weights; all-zero weights give the uniform distribution.
    pub fn new(weights: &[f32]) -> Distribution1D {
        let _ = weights;
        todo!("Distribution1D::new")
    }
    pub fn len(&self) -> usize {
        self.func.len()
    }
    pub fn is_empty(&self) -> bool {
        self.func.is_empty()
    }
    /// Discrete choice: `(index, probability of index, u remapped to [0,1) inside its interval)`.
    pub fn sample_discrete(&self, u: f32) -> (usize, f32, f32) {
        let _ = u;
        todo!("Distribution1D::sample_discrete")
    }
    /// Probability of choosing `index` discretely.
    pub fn pdf_discrete(&self, index: usize) -> f32 {
        let _ = index;
        todo!("Distribution1D::pdf_discrete")
    }
}
