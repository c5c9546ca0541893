//! What an RSA operator has for an exam, and nothing more: the nominal set-up, the bead tables
//! and model files of `OUT/phantoms/`, and the images of each run folder.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use glam::DVec3;

use crate::diagnostic::Diagnostic;
use crate::expand::{Run, expand_run};
use crate::output::received::{MAX_IMAGE_BYTES, MAX_TABLE_BYTES, ReceivedFolder};
use crate::phantom::{self, TriMesh};
use crate::scenario::{self, PoseRange, PositionRange, Scenario};
use exr::prelude::{ReadChannels, ReadLayers};

/// A bead of a phantom's table (`phantoms/<id>.csv` or `phantoms/<id>-beads.csv`), in the
/// phantom's own frame (the box frame for the calibration box).
#[derive(Debug, Clone, PartialEq)]
pub struct TableBead {
    /// Bead id.
    pub id: String,
    /// Plate id (calibration boxes), or empty.
    pub plate: String,
    /// Centre, mm.
    pub position_mm: DVec3,
    /// Diameter, mm.
    pub diameter_mm: f64,
}

/// The set-up as the operator knows it.
pub struct Setup {
    /// The scenario as run (`OUT/scenario.toml`).
    pub scenario: Scenario,
    /// The nominal geometry: every pose without its random draw, in the box frame.
    pub nominal: Run,
    /// Bead tables by phantom id.
    pub beads: BTreeMap<String, Vec<TableBead>>,
    /// Model meshes (from the files of `OUT/phantoms/`, in each phantom's local frame, mm) by
    /// phantom id.
    pub meshes: BTreeMap<String, Arc<TriMesh>>,
    /// Attenuation mode: the nominal imaging resolved into numbers (spectrum, materials'
    /// attenuation, detector absorption), as the operator knows the tube, the detector and the
    /// implant's material. `None` in binary mode.
    pub physics: Option<crate::attenuation::Setup>,
}

/// Reads `OUT/scenario.toml`, the bead tables and the model meshes of `OUT/phantoms/`.
pub fn load_setup(out: &Path) -> Result<Setup, Vec<Diagnostic>> {
    crate::output::check_output_folder(out)?;
    let loaded = scenario::load(&out.join("scenario.toml"))?;
    let mut nominal_scenario = loaded.scenario.clone();
    for s in &mut nominal_scenario.sources {
        s.randomize = PositionRange::default();
    }
    for d in &mut nominal_scenario.detectors {
        d.randomize = PoseRange::default();
    }
    for p in &mut nominal_scenario.phantoms {
        p.randomize = PoseRange::default();
    }
    let models = phantom::build(&loaded)?;
    let nominal = expand_run(
        &nominal_scenario,
        &models,
        0,
        crate::scenario::Level {
            noise_level: 0.0,
            exposure_factor: None,
        },
        0,
    );
    let folder = ReceivedFolder::unlisted(out);
    let mut beads = BTreeMap::new();
    for p in &loaded.scenario.phantoms {
        let name = if p.mesh.is_some() {
            format!("{}-beads.csv", p.id)
        } else {
            format!("{}.csv", p.id)
        };
        let rel = format!("phantoms/{name}");
        if folder.exists(&rel) {
            let bytes = folder.read(&rel, MAX_TABLE_BYTES).map_err(|d| vec![d])?;
            beads.insert(p.id.clone(), parse_bead_table(&folder.path(&rel), &bytes)?);
        }
    }
    let physics = if loaded.scenario.imaging.is_attenuation() {
        Some(crate::attenuation::Setup::build(&loaded, &models)?)
    } else {
        None
    };
    let meshes = models
        .into_iter()
        .filter_map(|m| m.mesh.map(|mesh| (m.id, mesh)))
        .collect();
    Ok(Setup {
        scenario: loaded.scenario,
        nominal,
        beads,
        meshes,
        physics,
    })
}

/// Reads a bead table: `id,plate,role,x_mm,y_mm,z_mm,diameter_mm`.
pub fn read_bead_table(file: &Path) -> Result<Vec<TableBead>, Vec<Diagnostic>> {
    let bytes = crate::output::received::read_named(file, MAX_TABLE_BYTES).map_err(|d| vec![d])?;
    parse_bead_table(file, &bytes)
}

/// Parses a bead table read from `file` (see [`read_bead_table`]).
fn parse_bead_table(file: &Path, bytes: &[u8]) -> Result<Vec<TableBead>, Vec<Diagnostic>> {
    let mut reader = csv::Reader::from_reader(bytes);
    let mut out = Vec::new();
    for (k, row) in reader.records().enumerate() {
        let bad = |what: String| {
            let mut d = Diagnostic::file_error(file, what)
                .with_help("columns: id,plate,role,x_mm,y_mm,z_mm,diameter_mm");
            d.line_col = Some((k + 2, 1));
            vec![d]
        };
        let row = row.map_err(|e| bad(format!("malformed row: {e}")))?;
        let num = |i: usize| {
            row.get(i)
                .and_then(|v| v.parse::<f64>().ok())
                .ok_or_else(|| bad(format!("column {} is not a number", i + 1)))
        };
        out.push(TableBead {
            id: row.get(0).unwrap_or("").to_string(),
            plate: row.get(1).unwrap_or("").to_string(),
            position_mm: DVec3::new(num(3)?, num(4)?, num(5)?),
            diameter_mm: num(6)?,
        });
    }
    Ok(out)
}

/// The run folders of `OUT/runs`, sorted by name.
pub fn run_folders(out: &Path) -> Result<Vec<(String, PathBuf)>, Vec<Diagnostic>> {
    let folder = ReceivedFolder::unlisted(out);
    let names = folder.sub_folders("runs").map_err(|d| vec![d])?;
    Ok(names
        .into_iter()
        .map(|name| {
            let dir = folder.path(&format!("runs/{name}"));
            (name, dir)
        })
        .collect())
}

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
