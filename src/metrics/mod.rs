//! Error metrics and convergence studies.
