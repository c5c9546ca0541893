//! What a scenario will cost, computed from the scenario alone (never by expanding its runs):
//! runs, images, bytes on disk per format, and the peak memory of the simulation; and the
//! documented caps that refuse a scenario before anything runs.
//!
//! # Caps (each overridable with `--allow-large`, except the TIFF format limit)
//!
//! - [`MAX_RUNS`] runs: the paper's protocol is 100 runs; 100,000 is a thousand such protocols,
//!   and a typo (`runs_per_level = 1000000000`) is caught instead of running for years.
//! - [`MAX_PIXELS_PER_IMAGE`] pixels per image: the largest flat-panel detectors have about
//!   20 megapixels (43 × 43 cm at 0.1 mm); 100 megapixels leaves room for oversampled studies.
//! - [`MAX_TOTAL_BYTES`] on disk (upper bound): a terabyte is more than a lab keeps per study.
//! - peak memory above what this machine has available (`MemAvailable` of `/proc/meminfo` on
//!   Linux; not checked elsewhere): the run would be killed or swap for hours.
//! - a classic TIFF file is addressed by 32-bit offsets: an image whose TIFF can exceed 4 GiB is
//!   refused (no override; choose `formats = ["exr"]` or fewer pixels).
//! - a DICOM data element's length is a 32-bit number: an image whose pixel data exceed
//!   [`DICOM_MAX_PIXEL_DATA_BYTES`] is refused as DICOM (no override).
//!
//! # Memory model (measured)
//!
//! Each rayon thread renders one image at a time: the clean projection and the noise field
//! (2 bytes per pixel each), the EXR samples (4) and the encoded files (up to 2 + 4), plus
//! encoder buffers. `/usr/bin/time -v` on a 2000 × 2000 detector measured 8 MB for a 64 × 64
//! scenario and 58 MB (one image in flight) and 105 MB (two threads) for 2000 × 2000 with TIFF
//! and EXR: 12.5 bytes per pixel per thread. The estimate uses [`BYTES_PER_PIXEL_IN_FLIGHT`]
//! = 14, plus [`BASE_MEMORY_BYTES`], the meshes with their BVHs, and the expanded runs with
//! their manifest entries (kept until the manifest is written).

use crate::diagnostic::{Diagnostic, KeyPath, Locator};
use crate::phantom::PhantomModel;
use crate::scenario::{ImageFormat, Scenario, TiffCompression};

/// Most runs a scenario may have without `--allow-large`.
pub const MAX_RUNS: u64 = 100_000;
/// Most pixels per image without `--allow-large` (100 megapixels).
pub const MAX_PIXELS_PER_IMAGE: u64 = 100_000_000;
/// Most bytes on disk (upper bound) without `--allow-large` (1 TB).
pub const MAX_TOTAL_BYTES: u64 = 1_000_000_000_000;
/// A classic TIFF file addresses its data with 32-bit offsets.
pub const CLASSIC_TIFF_MAX_BYTES: u64 = u32::MAX as u64;
/// Longest DICOM Pixel Data value: its length is a 32-bit number, and `FFFFFFFF` means
/// "undefined length".
pub const DICOM_MAX_PIXEL_DATA_BYTES: u64 = u32::MAX as u64 - 1;
/// Upper bound of a DICOM file's bytes besides its pixel data (preamble, file meta group and
/// the attributes of `output::dicom`: 1.8 kB measured), with margin.
pub const DICOM_HEADER_BYTES: u64 = 16_384;
/// Memory of one image in flight, per pixel, with margin over the 12.5 measured.
pub const BYTES_PER_PIXEL_IN_FLIGHT: u64 = 14;
/// Memory of the program itself with a tiny scenario (8 MB measured), with margin.
pub const BASE_MEMORY_BYTES: u64 = 16_000_000;
/// The flag that lifts the caps.
pub const OVERRIDE_FLAG: &str = "--allow-large";

/// What a scenario will write and use.
#[derive(Debug, Clone, PartialEq)]
pub struct Cost {
    /// Runs of the protocol.
    pub runs: u64,
    /// Images (exposure × detector × run), each written once per format (DICOM: once per
    /// intent).
    pub images: u64,
    /// Upper bound of the bytes of every image of each format (DICOM: all intents).
    pub image_bytes: Vec<(ImageFormat, u64)>,
    /// Upper bound of everything written: images, truth files, phantoms, manifest.
    pub total_bytes: u64,
    /// Estimated peak resident memory of the simulation.
    pub peak_memory_bytes: u64,
    /// Worker threads the estimate assumes (rayon's pool).
    pub threads: u64,
}

impl Cost {
    /// Estimates the cost of `s` with its built phantoms, for `threads` worker threads.
    pub fn estimate(s: &Scenario, models: &[PhantomModel], threads: usize) -> Cost {
        let threads = threads.max(1) as u64;
        let runs = s.run_count();
        let per_run_images = (s.exposures.len() * s.detectors.len()) as u64;
        let images = runs.saturating_mul(per_run_images);
        let image_bytes: Vec<(ImageFormat, u64)> = s
            .output
            .formats
            .iter()
            .map(|&f| {
                let files = s
                    .output
                    .image_files()
                    .iter()
                    .filter(|file| file.format() == f)
                    .count() as u64;
                let per_run: u64 = s
                    .detectors
                    .iter()
                    .map(|d| image_bytes_bound(f, s.output.tiff_compression, d.pixels))
                    .fold(0u64, u64::saturating_add)
                    .saturating_mul(s.exposures.len() as u64 * files);
                (f, per_run.saturating_mul(runs))
            })
            .collect();
        let markers: u64 = models.iter().map(|m| m.markers.len() as u64).sum();
        let image_markers: u64 = s
            .exposures
            .iter()
            .flat_map(|e| &e.phantoms)
            .filter_map(|id| models.iter().find(|m| &m.id == id))
            .map(|m| m.markers.len() as u64)
            .sum::<u64>()
            * s.detectors.len() as u64;
        // truth.json: the run's poses, then every image's projected beads (measured on the
        // shipped scenarios: about 250 bytes per bead and 160 per projected bead).
        let truth_per_run = 2_000
            + 700 * (s.sources.len() + s.detectors.len() + s.phantoms.len()) as u64
            + 250 * markers
            + 400 * per_run_images
            + 160 * image_markers;
        let files_per_run = per_run_images * s.output.image_files().len() as u64 + 1;
        let manifest_entry = 200;
        let mesh_bytes: u64 = models
            .iter()
            .filter_map(|m| m.mesh_file.as_ref())
            .filter_map(|p| std::fs::metadata(p).ok())
            .map(|m| m.len())
            .sum();
        let fixed = 100_000 + mesh_bytes + 100 * markers;
        let total_bytes = image_bytes
            .iter()
            .map(|(_, b)| *b)
            .fold(0u64, u64::saturating_add)
            .saturating_add(runs.saturating_mul(truth_per_run + files_per_run * manifest_entry))
            .saturating_add(fixed);

        let largest_image: u64 = s
            .detectors
            .iter()
            .map(|d| u64::from(d.pixels[0]) * u64::from(d.pixels[1]))
            .max()
            .unwrap_or(0);
        // Attenuation mode also holds each volume's path lengths over its shadow's rectangle
        // (f64; at most the whole image each, beads are negligible) and, with
        // `path_length_layers`, a net length image per material (f64) and its EXR samples (f32).
        let per_pixel = if s.imaging.is_attenuation() {
            let volumes: u64 = models.iter().map(|m| m.volumes.len() as u64).sum();
            let layers = if s.imaging.path_length_layers {
                let materials = models
                    .iter()
                    .flat_map(|m| {
                        m.volumes
                            .iter()
                            .filter_map(|v| v.material.as_deref())
                            .chain((!m.markers.is_empty()).then_some(m.bead_material.as_str()))
                    })
                    .collect::<std::collections::BTreeSet<_>>()
                    .len() as u64;
                12 * materials
            } else {
                0
            };
            BYTES_PER_PIXEL_IN_FLIGHT + 8 * volumes + layers
        } else {
            BYTES_PER_PIXEL_IN_FLIGHT
        };
        // Area sampling or a focal spot: the pixel samples are traced one strip at a time
        // (`sampling::strip`): per strip its hits (binary, u16) or every volume's path lengths
        // and three expected values (attenuation, f64); per image the covered fraction (f64)
        // and a count (u32), or three expected images (f64). The detector's blur, scatter and
        // electronic noise hold about four more f64 images.
        let im = &s.imaging;
        let (per_pixel, strip_bytes) = if im.is_point_sampled() {
            (per_pixel, 0)
        } else {
            let n = u64::from(im.samples_per_side());
            let samples = largest_image
                .saturating_mul(n * n)
                .min(crate::sampling::strip::STRIP_SAMPLES as u64);
            if im.is_attenuation() {
                let volumes: u64 = models.iter().map(|m| m.volumes.len() as u64).sum();
                (per_pixel + 24, samples.saturating_mul(8 * volumes + 24))
            } else {
                (per_pixel + 12, samples.saturating_mul(2))
            }
        };
        let d = &im.detector;
        let blurred = im.is_attenuation()
            && (d.psf.is_some()
                || d.mtf.is_some()
                || d.scatter.is_some()
                || d.electronic_noise_dn.is_some_and(|e| e > 0.0));
        let per_pixel = per_pixel + if blurred { 32 } else { 0 };
        let in_flight = largest_image
            .saturating_mul(per_pixel)
            .saturating_add(strip_bytes)
            .saturating_mul(threads.min(runs.max(1)));
        let mesh_memory: u64 = models
            .iter()
            .filter_map(|m| m.mesh.as_ref())
            .map(|m| 40 * m.vertices.len() as u64 + 200 * m.triangles.len() as u64)
            .sum::<u64>()
            + mesh_bytes;
        // Each expanded run (its poses and beads) and its manifest entries stay in memory until
        // the manifest is written.
        let per_run_memory = 1_000 + 100 * markers + 250 * files_per_run;
        let peak_memory_bytes = BASE_MEMORY_BYTES
            .saturating_add(in_flight)
            .saturating_add(mesh_memory)
            .saturating_add(runs.saturating_mul(per_run_memory));
        Cost {
            runs,
            images,
            image_bytes,
            total_bytes,
            peak_memory_bytes,
            threads,
        }
    }

    /// One line for `validate`: "100 runs, 400 images, at most 2.5 GB on disk, about 90 MB of
    /// memory".
    pub fn summary(&self) -> String {
        let formats: Vec<String> = self
            .image_bytes
            .iter()
            .map(|(f, b)| format!("{} {}", f.extension(), human_bytes(*b)))
            .collect();
        format!(
            "{} runs, {} images per format, at most {} on disk ({}), about {} of memory with {} threads",
            self.runs,
            self.images,
            human_bytes(self.total_bytes),
            formats.join(", "),
            human_bytes(self.peak_memory_bytes),
            self.threads
        )
    }

    /// Errors for everything beyond a cap (unless `allow_large`) or beyond the TIFF format, each
    /// at the key that causes it. `available_memory` is this machine's free memory, if known.
    pub fn check(
        &self,
        s: &Scenario,
        loc: &Locator,
        allow_large: bool,
        available_memory: Option<u64>,
    ) -> Vec<Diagnostic> {
        let mut out = Vec::new();
        let root = KeyPath::root();
        let override_help = |what: &str| {
            format!(
                "{what}; if this is really meant, pass {OVERRIDE_FLAG} (see the manual, docs/src/reference/limits.md)"
            )
        };
        for (i, d) in s.detectors.iter().enumerate() {
            let key = root.key("detectors").index(i).key("pixels");
            let pixels = u64::from(d.pixels[0]) * u64::from(d.pixels[1]);
            if s.output.formats.contains(&ImageFormat::Tiff) {
                let bound =
                    image_bytes_bound(ImageFormat::Tiff, s.output.tiff_compression, d.pixels);
                if bound > CLASSIC_TIFF_MAX_BYTES {
                    out.push(
                        loc.error(
                            key.clone(),
                            format!(
                                "a {} × {} image of detector `{}` can take up to {} as TIFF, more than the 4 GiB a classic TIFF file can hold",
                                d.pixels[0], d.pixels[1], crate::diagnostic::cut(&d.id), human_bytes(bound)
                            ),
                        )
                        .with_help("write only EXR (`[output] formats = [\"exr\"]`) or use fewer pixels"),
                    );
                    continue;
                }
            }
            if s.output.formats.contains(&ImageFormat::Dicom)
                && pixels * 2 > DICOM_MAX_PIXEL_DATA_BYTES
            {
                out.push(
                    loc.error(
                        key.clone(),
                        format!(
                            "a {} × {} image of detector `{}` has {} of pixel data, more than the 4 GiB a DICOM data element can hold",
                            d.pixels[0], d.pixels[1], crate::diagnostic::cut(&d.id), human_bytes(pixels * 2)
                        ),
                    )
                    .with_help("leave \"dicom\" out of `[output] formats` or use fewer pixels"),
                );
                continue;
            }
            if !allow_large && pixels > MAX_PIXELS_PER_IMAGE {
                out.push(
                    loc.error(
                        key,
                        format!(
                            "detector `{}` has {} × {} = {:.0} megapixels per image, more than the cap of {} megapixels",
                            crate::diagnostic::cut(&d.id),
                            d.pixels[0],
                            d.pixels[1],
                            pixels as f64 / 1e6,
                            MAX_PIXELS_PER_IMAGE / 1_000_000
                        ),
                    )
                    .with_help(override_help("clinical detectors have up to about 20 megapixels")),
                );
            }
        }
        if allow_large {
            return out;
        }
        if self.runs > MAX_RUNS {
            out.push(match &s.study {
                Some(d) => loc
                    .error(
                        root.key("study").key("patients"),
                        format!(
                            "the study has {} runs ({} patients × {} exams), more than the cap of {MAX_RUNS}",
                            self.runs,
                            d.patients,
                            d.exams.len()
                        ),
                    )
                    .with_help(override_help("check patients for a typo")),
                None if s.sequence.is_some() => loc
                    .error(
                        root.key("sequence").key("frames"),
                        format!(
                            "the protocol has {} runs ({} levels × {} runs per level × {} frames: each frame is a run), more than the cap of {MAX_RUNS}",
                            self.runs,
                            s.levels().len(),
                            s.protocol.runs_per_level,
                            s.frames_per_run()
                        ),
                    )
                    .with_help(override_help("check frames and runs_per_level for a typo")),
                None => loc
                    .error(
                        root.key("protocol").key("runs_per_level"),
                        format!(
                            "the protocol has {} runs ({} levels × {} runs per level), more than the cap of {MAX_RUNS}",
                            self.runs,
                            s.levels().len(),
                            s.protocol.runs_per_level
                        ),
                    )
                    .with_help(override_help("check runs_per_level for a typo (the paper uses 20)")),
            });
        }
        if self.total_bytes > MAX_TOTAL_BYTES {
            out.push(
                loc.error(
                    root.key("protocol").key("runs_per_level"),
                    format!(
                        "the output can take up to {} on disk ({} images per format), more than the cap of {}",
                        human_bytes(self.total_bytes),
                        self.images,
                        human_bytes(MAX_TOTAL_BYTES)
                    ),
                )
                .with_help(override_help("use fewer runs, detectors, pixels or formats")),
            );
        }
        if let Some(available) = available_memory
            && self.peak_memory_bytes > available
        {
            out.push(
                    loc.error(
                        root.key("detectors"),
                        format!(
                            "the simulation needs about {} of memory ({} threads), but this machine has {} available",
                            human_bytes(self.peak_memory_bytes),
                            self.threads,
                            human_bytes(available)
                        ),
                    )
                    .with_help(override_help(
                        "use fewer pixels or runs, fewer threads (RAYON_NUM_THREADS=1), or a larger machine",
                    )),
                );
        }
        out
    }
}

/// Upper bound of one image file's bytes: uncompressed samples plus the worst-case growth of
/// the compression and the headers (a compressor that does not shrink a block still writes it).
pub fn image_bytes_bound(format: ImageFormat, tiff: TiffCompression, pixels: [u32; 2]) -> u64 {
    let [w, h] = pixels.map(u64::from);
    match format {
        ImageFormat::Tiff => {
            let raw = w * h * 2;
            let grown = match tiff {
                TiffCompression::None => raw,
                // Deflate's stored blocks: 5 bytes per 64 KiB, plus a zlib frame per strip.
                TiffCompression::Deflate => raw + raw / 1_000,
                // Packbits: one header byte per 128 literal bytes.
                TiffCompression::Packbits => raw + raw / 128 + h,
                // LZW: at most one 12-bit code per input byte.
                TiffCompression::Lzw => raw + raw / 2,
            };
            grown + 16 * h + 4_096
        }
        // EXR blocks that do not shrink are stored raw; 4 bytes per sample, an offset and a
        // block header per scanline at most.
        ImageFormat::Exr => w * h * 4 + 16 * h + 4_096,
        // Native (uncompressed) 16-bit pixels and the header, per intent.
        ImageFormat::Dicom => w * h * 2 + DICOM_HEADER_BYTES,
    }
}

/// `MemAvailable` of `/proc/meminfo` in bytes, on Linux; `None` elsewhere or if unreadable.
pub fn available_memory_bytes() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    parse_mem_available(&text)
}

fn parse_mem_available(meminfo: &str) -> Option<u64> {
    let line = meminfo.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

/// Bytes in decimal units: `512 B`, `2.5 GB`.
pub fn human_bytes(bytes: u64) -> String {
    const UNITS: [&str; 6] = ["B", "kB", "MB", "GB", "TB", "PB"];
    let mut value = bytes as f64;
    let mut unit = 0;
    while value >= 1000.0 && unit + 1 < UNITS.len() {
        value /= 1000.0;
        unit += 1;
    }
    if unit == 0 {
        format!("{bytes} B")
    } else if value < 10.0 {
        format!("{value:.1} {}", UNITS[unit])
    } else {
        format!("{value:.0} {}", UNITS[unit])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bytes_print_in_decimal_units() {
        assert_eq!(human_bytes(512), "512 B");
        assert_eq!(human_bytes(2_500_000_000), "2.5 GB");
        assert_eq!(human_bytes(90_000_000), "90 MB");
        assert_eq!(human_bytes(u64::MAX), "18447 PB");
    }

    #[test]
    fn mem_available_is_read_from_meminfo() {
        let text = "MemTotal: 100 kB\nMemFree: 10 kB\nMemAvailable:   2048 kB\n";
        assert_eq!(parse_mem_available(text), Some(2048 * 1024));
        assert_eq!(parse_mem_available("MemTotal: 1 kB\n"), None);
    }

    #[test]
    fn the_tiff_bound_crosses_4_gib_where_the_encoder_fails() {
        // 46341² 16-bit samples are just over 4 GiB; 46340² just under (plus headers).
        let at = |n| image_bytes_bound(ImageFormat::Tiff, TiffCompression::None, [n, n]);
        assert!(at(46_341) > CLASSIC_TIFF_MAX_BYTES);
        assert!(at(46_000) < CLASSIC_TIFF_MAX_BYTES);
        assert!(image_bytes_bound(ImageFormat::Exr, TiffCompression::None, [10, 10]) >= 400);
        assert_eq!(
            image_bytes_bound(ImageFormat::Dicom, TiffCompression::None, [10, 20]),
            400 + DICOM_HEADER_BYTES
        );
    }
}
