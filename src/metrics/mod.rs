//! Error metrics and convergence studies: how far an image is from a reference (`compare`), how
//! that error falls with render time for each integrator (`converge`), and the plots of it
//! (`plot`).

pub mod compare;
pub mod converge;
pub mod plot;
