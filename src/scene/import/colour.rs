//! Colour values of Mitsuba files reduced to the linear sRGB plexus renders with: `rgb`, `srgb`
//! (gamma-decoded), `spectrum` (one value, or wavelength:value pairs integrated against the CIE 1931
//! colour matching functions), the named conductor presets (`material="Au"`) as RGB η and k, and
//! the named indices of refraction (`int_ior="bk7"`).

use super::xml::Loc;
use super::ImportError;

/// A colour as written in the file.
#[derive(Clone, Debug, PartialEq)]
pub enum Spectrum {
    Uniform(f64),
    Rgb([f64; 3]),
    /// (wavelength in nm, value), increasing wavelengths.
    List(Vec<(f64, f64)>),
}

impl Spectrum {
    /// Linear sRGB. Wavelength lists follow Mitsuba 3's reduction in its RGB modes: a reflectance
    /// is integrated under a D65-like illuminant (so that a flat spectrum stays grey: here a 6504 K
    /// black body, which D65 approximates), an emitter's radiance without one, both normalised by
    /// ∫ȳ of the same weighting; zero outside the listed range.
    pub fn to_rgb(&self, emitter: bool) -> [f64; 3] {
        match self {
            Spectrum::Uniform(v) => [*v; 3],
            Spectrum::Rgb(c) => *c,
            Spectrum::List(pairs) => list_to_rgb(pairs, emitter),
        }
    }
}

pub fn parse_rgb(s: &str, loc: &Loc) -> Result<[f64; 3], ImportError> {
    let v = super::numbers::parse_list(s, loc)?;
    match v.as_slice() {
        [g] => Ok([*g; 3]),
        [r, g, b] => Ok([*r, *g, *b]),
        _ => Err(ImportError::at(loc, format!("expected one or three numbers for an rgb value, got '{s}'"))),
    }
}

/// `#rrggbb` or numbers in [0, 1], both sRGB-encoded, decoded to linear.
pub fn parse_srgb(s: &str, loc: &Loc) -> Result<[f64; 3], ImportError> {
    let t = s.trim();
    let encoded = if let Some(hex) = t.strip_prefix('#') {
        if hex.len() != 6 || !hex.chars().all(|c| c.is_ascii_hexdigit()) {
            return Err(ImportError::at(loc, format!("expected '#rrggbb', got '{s}'")));
        }
        let byte = |i: usize| u8::from_str_radix(&hex[i..i + 2], 16).map(|b| b as f64 / 255.0).unwrap_or(0.0);
        [byte(0), byte(2), byte(4)]
    } else {
        parse_rgb(t, loc)?
    };
    Ok(encoded.map(srgb_to_linear))
}

pub fn srgb_to_linear(v: f64) -> f64 {
    if v <= 0.04045 {
        v / 12.92
    } else {
        ((v + 0.055) / 1.055).powf(2.4)
    }
}

/// `400:0.5, 500:0.6, ...` or a single number.
pub fn parse_spectrum(s: &str, loc: &Loc) -> Result<Spectrum, ImportError> {
    if !s.contains(':') {
        let v = super::numbers::parse_list(s, loc)?;
        return match v.as_slice() {
            [g] => Ok(Spectrum::Uniform(*g)),
            _ => Err(ImportError::at(loc, format!("expected one number or wavelength:value pairs, got '{s}'"))),
        };
    }
    let mut pairs = Vec::new();
    for item in s.split(',').map(str::trim).filter(|t| !t.is_empty()) {
        let Some((w, v)) = item.split_once(':') else {
            return Err(ImportError::at(loc, format!("expected wavelength:value, got '{item}'")));
        };
        let (w, v) = (super::numbers::parse_f64(w, loc)?, super::numbers::parse_f64(v, loc)?);
        // Wavelengths in nanometres: a spectrum beyond (0, 10^5] (far infrared) is not light a
        // colour can be made of, and ±1e30 once passed unnoticed.
        if !(w > 0.0 && w <= 1e5) {
            return Err(ImportError::at(loc, format!("wavelength {w} is not in (0, 100000] nanometres")));
        }
        if let Some(&(prev, _)) = pairs.last() {
            if w <= prev {
                return Err(ImportError::at(loc, format!("wavelengths must increase, got {w} after {prev}")));
            }
        }
        pairs.push((w, v));
    }
    if pairs.len() < 2 {
        return Err(ImportError::at(loc, "expected at least two wavelength:value pairs"));
    }
    Ok(Spectrum::List(pairs))
}

/// CIE 1931 2° colour matching functions, the multi-lobe Gaussian fit of Wyman, Sloan and Shirley
/// (2013, "Simple Analytic Approximations to the CIE XYZ Color Matching Functions", Eq. 2): within
/// about 1% of the tabulated curves, which is far below what the reduction to RGB loses anyway.
fn cie_xyz(lambda: f64) -> [f64; 3] {
    let g = |x: f64, mu: f64, s1: f64, s2: f64| {
        let t = (x - mu) / if x < mu { s1 } else { s2 };
        (-0.5 * t * t).exp()
    };
    [
        1.056 * g(lambda, 599.8, 37.9, 31.0) + 0.362 * g(lambda, 442.0, 16.0, 26.7)
            - 0.065 * g(lambda, 501.1, 20.4, 26.2),
        0.821 * g(lambda, 568.8, 46.9, 40.5) + 0.286 * g(lambda, 530.9, 16.3, 31.1),
        1.217 * g(lambda, 437.0, 11.8, 36.0) + 0.681 * g(lambda, 459.0, 26.0, 13.8),
    ]
}

/// Relative spectral radiance of a black body at `t` kelvin (Planck's law, unnormalised).
fn planck(lambda_nm: f64, t: f64) -> f64 {
    const C2: f64 = 1.4387769e7; // h·c/k in nm·K
    let l = lambda_nm / 1000.0; // micrometres keep the numbers tame
    1.0 / (l.powi(5) * ((C2 / (lambda_nm * t)).exp() - 1.0))
}

fn xyz_to_linear_srgb([x, y, z]: [f64; 3]) -> [f64; 3] {
    [
        3.240479 * x - 1.537150 * y - 0.498535 * z,
        -0.969256 * x + 1.875991 * y + 0.041556 * z,
        0.055648 * x - 0.204043 * y + 1.057311 * z,
    ]
}

fn list_to_rgb(pairs: &[(f64, f64)], emitter: bool) -> [f64; 3] {
    let value_at = |w: f64| -> f64 {
        if w < pairs[0].0 || w > pairs[pairs.len() - 1].0 {
            return 0.0;
        }
        let i = pairs.partition_point(|p| p.0 <= w).clamp(1, pairs.len() - 1);
        let ((w0, v0), (w1, v1)) = (pairs[i - 1], pairs[i]);
        v0 + (v1 - v0) * (w - w0) / (w1 - w0)
    };
    let illuminant = |w: f64| if emitter { 1.0 } else { planck(w, 6504.0) };
    // XYZ of the spectrum and of the bare illuminant (the white), both per ∫ȳ·illuminant.
    let (mut xyz, mut white, mut norm) = ([0.0f64; 3], [0.0f64; 3], 0.0);
    let steps = 1000;
    for i in 0..steps {
        let w = 360.0 + (830.0 - 360.0) * (i as f64 + 0.5) / steps as f64;
        let (c, e, v) = (cie_xyz(w), illuminant(w), value_at(w));
        for k in 0..3 {
            xyz[k] += c[k] * v * e;
            white[k] += c[k] * e;
        }
        norm += c[1] * e;
    }
    let rgb = xyz_to_linear_srgb(xyz.map(|c| c / norm));
    if emitter {
        return rgb.map(|c| c.max(0.0));
    }
    // A reflectance: the illuminant's own colour becomes [1, 1, 1] (von Kries scaling in RGB),
    // so that a flat spectrum of 1 is white, as Mitsuba's D65-weighted reduction makes it.
    let white = xyz_to_linear_srgb(white.map(|c| c / norm));
    [0, 1, 2].map(|k| (rgb[k] / white[k]).max(0.0))
}

/// RGB η and k of Mitsuba's named conductors (its `material` parameter), integrated from the
/// spectral data Mitsuba ships the way its RGB modes do; "none" is the perfect mirror (handled by
/// the caller). The values are those Bitterli's Mitsuba scene conversions write out explicitly.
pub fn conductor_preset(name: &str) -> Option<([f64; 3], [f64; 3])> {
    Some(match name {
        "Ag" => ([0.155265, 0.116723, 0.138342], [4.82835, 3.12225, 2.14696]),
        "Al" => ([1.65746, 0.880369, 0.521229], [9.22387, 6.26952, 4.837]),
        "Au" => ([0.143119, 0.374957, 1.44248], [3.98316, 2.38572, 1.60322]),
        "Cr" => ([4.36968, 2.9167, 1.6547], [5.20643, 4.23136, 3.75495]),
        "Cu" => ([0.200438, 0.924033, 1.10221], [3.91295, 2.45285, 2.14219]),
        _ => return None,
    })
}

/// Names of conductor presets `conductor_preset` knows, for messages.
pub const CONDUCTOR_PRESETS: &str = "Ag, Al, Au, Cr, Cu, none";

/// Mitsuba's named indices of refraction.
pub fn named_ior(name: &str) -> Option<f64> {
    Some(match name.to_ascii_lowercase().as_str() {
        "vacuum" => 1.0,
        "helium" => 1.000036,
        "hydrogen" => 1.000132,
        "air" => 1.000277,
        "carbon dioxide" => 1.00045,
        "water" => 1.333,
        "acetone" => 1.36,
        "ethanol" => 1.361,
        "carbon tetrachloride" => 1.461,
        "glycerol" => 1.4729,
        "benzene" => 1.501,
        "silicone oil" => 1.52045,
        "bromine" => 1.661,
        "water ice" => 1.31,
        "fused quartz" => 1.458,
        "pyrex" => 1.470,
        "acrylic glass" => 1.49,
        "polypropylene" => 1.49,
        "bk7" => 1.5046,
        "sodium chloride" => 1.544,
        "amber" => 1.55,
        "pet" => 1.5750,
        "diamond" => 2.419,
        _ => return None,
    })
}

/// Normal-incidence reflectance of a conductor, ((η−1)² + k²)/((η+1)² + k²) per channel.
pub fn conductor_f0(eta: [f64; 3], k: [f64; 3]) -> [f64; 3] {
    [0, 1, 2].map(|i| {
        let (n, k) = (eta[i], k[i]);
        ((n - 1.0).powi(2) + k * k) / ((n + 1.0).powi(2) + k * k)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn loc() -> Loc {
        Loc { file: "t.xml".into(), line: 1 }
    }

    #[test]
    fn flat_reflectance_stays_grey_and_colours_land_in_their_channel() {
        let flat = parse_spectrum("400:0.78, 500:0.78, 600:0.78, 700:0.78", &loc()).unwrap().to_rgb(false);
        // Flat over 400–700 nm only (zero outside, as Mitsuba), so a little below 0.78, but grey.
        for c in flat {
            assert!((c - 0.78).abs() < 0.03, "{flat:?}");
        }
        assert!((flat[0] - flat[2]).abs() < 0.02, "{flat:?}");
        // A red reflectance (the Cornell box's red wall: high above 600 nm) is red.
        let red = parse_spectrum("400:0.05, 580:0.05, 600:0.6, 700:0.64", &loc()).unwrap().to_rgb(false);
        assert!(red[0] > 0.3 && red[1] < 0.1 && red[2] < 0.1, "{red:?}");
        let blue = parse_spectrum("400:0.8, 480:0.8, 500:0.05, 700:0.05", &loc()).unwrap().to_rgb(false);
        assert!(blue[2] > 0.4 && blue[0] < 0.1, "{blue:?}");
        assert_eq!(parse_spectrum("0.25", &loc()).unwrap().to_rgb(false), [0.25; 3]);
        assert!(parse_spectrum("500:1, 400:2", &loc()).is_err());
    }

    /// Against Mitsuba 3.9.1's own reduction (`mi.spectrum_list_to_srgb`, scalar_rgb), measured
    /// on the Cornell box's spectra: light [41.4216, 21.7093, 5.5423], red wall
    /// [0.49132, 0.049228, 0.0509219]. The analytic CIE fit and the black-body D65 stand-in stay
    /// within 2.5% (this is the Cornell box's model tolerance in the cross-check).
    #[test]
    fn spectra_reduce_as_mitsuba_3_does() {
        let light = parse_spectrum("400:0, 500:16, 600:31.2, 700:36.8", &loc()).unwrap().to_rgb(true);
        for (got, want) in light.iter().zip([41.4216, 21.7093, 5.5423]) {
            assert!((got / want - 1.0).abs() < 0.01, "{light:?}");
        }
        // The red wall of Mitsuba's Cornell box (its `cbox.xml`).
        let red = "400:0.04, 404:0.046, 408:0.048, 412:0.053, 416:0.049, 420:0.05, 424:0.053, 428:0.055, \
                   432:0.057, 436:0.056, 440:0.059, 444:0.057, 448:0.061, 452:0.061, 456:0.06, 460:0.062, \
                   464:0.062, 468:0.062, 472:0.061, 476:0.062, 480:0.06, 484:0.059, 488:0.057, 492:0.058, \
                   496:0.058, 500:0.058, 504:0.056, 508:0.055, 512:0.056, 516:0.059, 520:0.057, 524:0.055, \
                   528:0.059, 532:0.059, 536:0.058, 540:0.059, 544:0.061, 548:0.061, 552:0.063, 556:0.063, \
                   560:0.067, 564:0.068, 568:0.072, 572:0.08, 576:0.09, 580:0.099, 584:0.124, 588:0.154, \
                   592:0.192, 596:0.255, 600:0.287, 604:0.349, 608:0.402, 612:0.443, 616:0.487, 620:0.513, \
                   624:0.558, 628:0.584, 632:0.62, 636:0.606, 640:0.609, 644:0.651, 648:0.612, 652:0.61, \
                   656:0.65, 660:0.638, 664:0.627, 668:0.62, 672:0.63, 676:0.628, 680:0.642, 684:0.639, \
                   688:0.657, 692:0.639, 696:0.635, 700:0.642";
        let red = parse_spectrum(red, &loc()).unwrap().to_rgb(false);
        assert!((red[0] / 0.49132 - 1.0).abs() < 0.025, "{red:?}");
        assert!((red[1] / 0.049228 - 1.0).abs() < 0.1 && (red[2] / 0.0509219 - 1.0).abs() < 0.1, "{red:?}");
    }

    #[test]
    fn srgb_and_rgb_parse() {
        assert_eq!(parse_rgb("0.1, 0.2 0.3", &loc()).unwrap(), [0.1, 0.2, 0.3]);
        assert_eq!(parse_rgb("0.5", &loc()).unwrap(), [0.5; 3]);
        assert!(parse_rgb("1 2", &loc()).is_err());
        let c = parse_srgb("#ff8000", &loc()).unwrap();
        assert!((c[0] - 1.0).abs() < 1e-9 && (c[1] - 0.2158605).abs() < 1e-6 && c[2] == 0.0, "{c:?}");
    }

    #[test]
    fn presets_are_plausible_metals() {
        // Gold reflects red more than blue; aluminium is bright and nearly neutral.
        let (eta, k) = conductor_preset("Au").unwrap();
        let f = conductor_f0(eta, k);
        assert!(f[0] > 0.9 && f[2] < 0.5, "{f:?}");
        let (eta, k) = conductor_preset("Al").unwrap();
        let f = conductor_f0(eta, k);
        assert!(f.iter().all(|&c| c > 0.9), "{f:?}");
        assert_eq!(named_ior("BK7"), Some(1.5046));
    }
}
