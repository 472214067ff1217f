//! TEMPORARY: `film::exr_io::read_exr` is being written by its owner. Until it is committed the
//! scene reads environment maps here; this file then goes away.

use std::path::Path;

use crate::film::Image;
use crate::spectrum::Rgb;

pub fn read_exr(path: &Path) -> Result<Image, String> {
    use exr::prelude::read_first_rgba_layer_from_file;
    let img = read_first_rgba_layer_from_file(
        path,
        |size, _| Image::new(size.width(), size.height()),
        |img: &mut Image, pos, (r, g, b, _a): (f32, f32, f32, f32)| {
            let w = img.width;
            img.pixels[pos.y() * w + pos.x()] = Rgb::new(r, g, b);
        },
    )
    .map_err(|e| e.to_string())?;
    Ok(img.layer_data.channel_data.pixels)
}
