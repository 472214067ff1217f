//! The sun's direction from a date, time and place, as Mitsuba's `sunsky`/`sun` compute it when no
//! `sun_direction` is given: the PSA algorithm of Blanco-Muriel et al. (2001, "Computing the solar
//! vector", Solar Energy 70(5)), then Mitsuba's spherical convention (y up, azimuth from -z
//! towards +x).

use glam::DVec3;

/// When and where, with Mitsuba's defaults (Tokyo, 10 July 2010, 15:00 local time).
#[derive(Clone, Copy, Debug)]
pub struct SunTime {
    pub year: i64,
    pub month: i64,
    pub day: i64,
    pub hour: f64,
    pub minute: f64,
    pub second: f64,
    pub latitude: f64,
    pub longitude: f64,
    pub timezone: f64,
}

impl Default for SunTime {
    fn default() -> SunTime {
        SunTime {
            year: 2010,
            month: 7,
            day: 10,
            hour: 15.0,
            minute: 0.0,
            second: 0.0,
            latitude: 35.6894,
            longitude: 139.6917,
            timezone: 9.0,
        }
    }
}

/// Unit direction towards the sun in Mitsuba's local frame (y up), before `to_world`.
pub fn sun_direction(t: &SunTime) -> DVec3 {
    use std::f64::consts::PI;
    // Universal time in decimal hours and days since noon UT, 1 January 2000 (JD 2451545.0).
    let dec_hours = t.hour - t.timezone + (t.minute + t.second / 60.0) / 60.0;
    let aux1 = (t.month - 14) / 12;
    let aux2 = (1461 * (t.year + 4800 + aux1)) / 4 + (367 * (t.month - 2 - 12 * aux1)) / 12
        - (3 * ((t.year + 4900 + aux1) / 100)) / 4
        + t.day
        - 32075;
    let julian = aux2 as f64 - 0.5 + dec_hours / 24.0;
    let n = julian - 2451545.0;
    // Ecliptic coordinates.
    let omega = 2.1429 - 0.0010394594 * n;
    let mean_longitude = 4.8950630 + 0.017202791698 * n;
    let mean_anomaly = 6.2400600 + 0.0172019699 * n;
    let ecliptic_longitude = mean_longitude + 0.03341607 * mean_anomaly.sin() + 0.00034894 * (2.0 * mean_anomaly).sin()
        - 0.0001134
        - 0.0000203 * omega.sin();
    let obliquity = 0.4090928 - 6.2140e-9 * n + 0.0000396 * omega.cos();
    // Celestial coordinates.
    let sin_el = ecliptic_longitude.sin();
    let mut right_ascension = (obliquity.cos() * sin_el).atan2(ecliptic_longitude.cos());
    if right_ascension < 0.0 {
        right_ascension += 2.0 * PI;
    }
    let declination = (obliquity.sin() * sin_el).asin();
    // Local coordinates.
    let gmst = 6.6974243242 + 0.0657098283 * n + dec_hours;
    let lmst = (gmst * 15.0 + t.longitude).to_radians();
    let hour_angle = lmst - right_ascension;
    let lat = t.latitude.to_radians();
    let mut zenith =
        (lat.cos() * hour_angle.cos() * declination.cos() + declination.sin() * lat.sin()).clamp(-1.0, 1.0).acos();
    let mut azimuth = (-hour_angle.sin()).atan2(declination.tan() * lat.cos() - lat.sin() * hour_angle.cos());
    if azimuth < 0.0 {
        azimuth += 2.0 * PI;
    }
    // Parallax: Earth's mean radius over the astronomical unit (km).
    zenith += (6371.01 / 149597890.0) * zenith.sin();
    DVec3::new(azimuth.sin() * zenith.sin(), zenith.cos(), -azimuth.cos() * zenith.sin())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn noon_sun_is_high_and_morning_sun_is_east() {
        // Tokyo in July: about 78° high at local noon (latitude 35.7°, declination 22°).
        let noon = sun_direction(&SunTime { hour: 11.7, ..Default::default() });
        let elevation = noon.y.asin().to_degrees();
        assert!((elevation - 77.0).abs() < 3.0, "{elevation}");
        // At 9:00 it is in the east: azimuth from north (-z) towards east (+x).
        let morning = sun_direction(&SunTime { hour: 9.0, ..Default::default() });
        assert!(morning.x > 0.5 && morning.y > 0.3, "{morning}");
        // At midnight it is below the horizon.
        assert!(sun_direction(&SunTime { hour: 0.0, ..Default::default() }).y < 0.0);
    }
}
