//! Numbers in Mitsuba attributes: one finite number, or a list of them. Every reader of the
//! importer (objects, colours, transforms) parses through these, so they sit below all of them.

use super::xml::Loc;
use super::ImportError;

/// One finite number (`value="0.5"`); infinities and NaN are refused like any other non-number.
pub fn parse_f64(s: &str, loc: &Loc) -> Result<f64, ImportError> {
    let v: f64 = s.trim().parse().map_err(|_| ImportError::at(loc, format!("expected a number, got '{s}'")))?;
    if !v.is_finite() {
        return Err(ImportError::at(loc, format!("expected a finite number, got '{s}'")));
    }
    Ok(v)
}

/// Numbers separated by commas and/or white space.
pub fn parse_list(s: &str, loc: &Loc) -> Result<Vec<f64>, ImportError> {
    s.split(|c: char| c == ',' || c.is_whitespace()).filter(|t| !t.is_empty()).map(|t| parse_f64(t, loc)).collect()
}
