//! The images rsasim wrote, read back: a run's 16-bit grayscale TIFF ([`super::tiff`]) or, when
//! there is none, its EXR ([`super::exr`]), each opened through the gate for received folders
//! ([`super::received`]).

use std::path::Path;

use exr::prelude::{ReadChannels, ReadLayers};

use super::received::{MAX_IMAGE_BYTES, ReceivedFolder};

/// A grayscale image: `(width, height, pixels)`, from `<stem>.tiff` or else `<stem>.exr` of the
/// run folder `dir`, each opened through the gate for received folders (a regular file, not a
/// link, within [`MAX_IMAGE_BYTES`]); the decoders' own limits bound what a header can ask for.
pub fn read_image(dir: &Path, stem: &str) -> Result<(u32, u32, Vec<u16>), String> {
    let folder = ReceivedFolder::unlisted(dir);
    let tiff_name = format!("{stem}.tiff");
    if folder.exists(&tiff_name) {
        let tiff_path = folder.path(&tiff_name);
        let file = folder
            .open(&tiff_name, MAX_IMAGE_BYTES)
            .map_err(|d| format!("{}: {}", tiff_path.display(), d.message))?;
        let mut dec = tiff::decoder::Decoder::new(std::io::BufReader::new(file))
            .map_err(|e| format!("{}: {e}", tiff_path.display()))?;
        let (w, h) = dec.dimensions().map_err(|e| e.to_string())?;
        return match dec
            .read_image()
            .map_err(|e| format!("{}: {e}", tiff_path.display()))?
        {
            tiff::decoder::DecodingResult::U16(v)
                if v.len() as u64 == u64::from(w) * u64::from(h) =>
            {
                Ok((w, h, v))
            }
            _ => Err(format!(
                "{} is not a 16-bit grayscale TIFF",
                tiff_path.display()
            )),
        };
    }
    let exr_name = format!("{stem}.exr");
    let exr_path = folder.path(&exr_name);
    let file = folder
        .open(&exr_name, MAX_IMAGE_BYTES)
        .map_err(|d| format!("{}: {}", exr_path.display(), d.message))?;
    let image = exr::prelude::read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .from_buffered(std::io::BufReader::new(file))
        .map_err(|e| format!("{}: {e}", exr_path.display()))?;
    let size = image.layer_data.size;
    let Some(channel) = image.layer_data.channel_data.list.first() else {
        return Err(format!("{} has no channel", exr_path.display()));
    };
    let values: Vec<u16> = channel
        .sample_data
        .values_as_f32()
        .map(|v| v as u16)
        .collect();
    let (w, h) = (
        u32::try_from(size.0).map_err(|_| format!("{} is too wide", exr_path.display()))?,
        u32::try_from(size.1).map_err(|_| format!("{} is too tall", exr_path.display()))?,
    );
    if values.len() as u64 != u64::from(w) * u64::from(h) {
        return Err(format!(
            "{} holds {} values for {w} × {h} pixels",
            exr_path.display(),
            values.len()
        ));
    }
    Ok((w, h, values))
}
