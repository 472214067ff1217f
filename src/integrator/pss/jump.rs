//! The reversible-jump acceptance ratio of RJMLT (Bitterli et al. 2017), shared by the renderer's
//! technique jumps and the 1D validation chain of Sec. 7.1, so both run the same formula.

/// One side of a technique jump: the state's target value and how its primary samples relate to
/// the path through the (probabilistic) inverse.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JumpSide {
    /// Target of the state in primary sample space: ŵ·Ĉ* (MIS-weighted scalar contribution).
    pub target: f64,
    /// Probability T(· → other) of proposing the jump towards the other side's technique
    /// (T(i→j) = w_j, Eq. 33).
    pub technique_choice: f64,
    /// |J[S⁻¹](x, γ)| of this side's inverse mapping at the shared path x: for an injective
    /// technique its pdf; for a mixture α_t·|J[S_t⁻¹]| (Eq. 42); unused dimensions contribute 1.
    pub inverse_jacobian: f64,
    /// Probability with which the probabilistic inverse picks the branch this side's primary
    /// samples lie on (T(t) of Eq. 44; 1 where the inverse is unique).
    pub branch_choice: f64,
}

/// Acceptance ratio r((û,i) → (v̂,j)) of a technique jump: Eq. 38 with the mixture correction of
/// Eq. 43,
///   r = [C_j T(j→i) |J[S_j⁻¹]|] / [C_i T(i→j) |J[S_i⁻¹]|] · T(t_û) / T(t_v̂).
/// With T(i→j) = w_j and T(t) from Eq. 44 every factor cancels and r = 1 (Sec. 6.2); computing it
/// in full keeps that claim checkable. A zero or non-finite denominator (a current state that
/// should never have been accepted) gives 0: the jump is rejected rather than producing NaN.
pub fn jump_acceptance(current: &JumpSide, proposal: &JumpSide) -> f64 {
    let numerator = proposal.target * proposal.technique_choice * proposal.inverse_jacobian * current.branch_choice;
    let denominator = current.target * current.technique_choice * current.inverse_jacobian * proposal.branch_choice;
    let r = numerator / denominator;
    if r.is_finite() && r >= 0.0 {
        r
    } else {
        0.0
    }
}
