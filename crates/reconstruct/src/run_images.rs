//! The images of one run folder, each read and converted once however many steps use it.
//!
//! In a cage exam the box's beads, a bone's markers and an implant's outline are all found in
//! the same radiograph, and in any exam the markers and the outline of the models share the
//! model exposure. Each step used to decode the image, convert it to attenuation and segment the
//! implant's shadow again: three times per image of the 4-patient attenuation study. Each is now
//! done on first use and kept for the run. The results are those of the steps done afresh (the
//! same functions of the same inputs).

use std::collections::BTreeMap;
use std::path::Path;
use std::sync::{Arc, Mutex, OnceLock};

use super::density::{Density, Reading, density};
use super::shadow::{Shadow, dense_shadow};
use crate::expand::DetectorState;
use crate::output::decode::read_image;
use crate::scenario::Imaging;

/// The images of one run folder read so far, by file stem (`exposure-detector`).
pub struct RunImages<'d> {
    dir: &'d Path,
    imaging: &'d Imaging,
    read: Mutex<BTreeMap<String, Arc<RunImage>>>,
}

/// One decoded image and what has been derived from it.
pub struct RunImage {
    /// Width, pixels.
    pub width: usize,
    /// The pixel values, row-major.
    pub pixels: Vec<u16>,
    /// How its values read as attenuation (its detector's).
    reading: Reading,
    density: OnceLock<Density>,
    /// The implant's dense shadow by the expected area it was segmented for (its bits).
    shadows: Mutex<Vec<(Option<u64>, Option<Arc<Shadow>>)>>,
}

impl<'d> RunImages<'d> {
    /// No image of the run folder `dir`, made with `imaging`, read yet.
    pub fn new(dir: &'d Path, imaging: &'d Imaging) -> RunImages<'d> {
        RunImages {
            dir,
            imaging,
            read: Mutex::new(BTreeMap::new()),
        }
    }

    /// The image of `exposure` on detector `det` (file stem `exposure-detector`), decoded on
    /// first use.
    pub fn get(&self, exposure: &str, det: &DetectorState) -> Result<Arc<RunImage>, String> {
        let stem = format!("{exposure}-{}", det.id);
        let mut read = self.read.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(image) = read.get(&stem) {
            return Ok(Arc::clone(image));
        }
        let (width, _, pixels) = read_image(self.dir, &stem)?;
        let image = Arc::new(RunImage {
            width: width as usize,
            pixels,
            reading: Reading::of(self.imaging, det.i_max()),
            density: OnceLock::new(),
            shadows: Mutex::new(Vec::new()),
        });
        read.insert(stem, Arc::clone(&image));
        Ok(image)
    }
}

impl RunImage {
    /// The image as attenuation, read as its detector says.
    pub fn density(&self) -> &Density {
        self.density
            .get_or_init(|| density(&self.pixels, self.width, self.reading))
    }

    /// [`dense_shadow`] of the image's attenuation, for `expected_area_px`.
    pub fn dense_shadow(&self, expected_area_px: Option<f64>) -> Option<Arc<Shadow>> {
        let key = expected_area_px.map(f64::to_bits);
        let mut shadows = self.shadows.lock().unwrap_or_else(|e| e.into_inner());
        if let Some((_, shadow)) = shadows.iter().find(|(k, _)| *k == key) {
            return shadow.clone();
        }
        let shadow = dense_shadow(self.density(), expected_area_px).map(Arc::new);
        shadows.push((key, shadow.clone()));
        shadow
    }
}
