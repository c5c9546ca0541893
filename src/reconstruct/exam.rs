//! What an RSA operator has for an exam, and nothing more: the nominal set-up, the bead tables
//! and model files of `OUT/phantoms/`, and the run folders (whose images
//! [`crate::output::decode::read_image`] reads).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use glam::DVec3;

use crate::diagnostic::Diagnostic;
use crate::expand::{Run, expand_run};
use crate::output::received::{MAX_TABLE_BYTES, ReceivedFolder};
use crate::phantom::{self, TriMesh};
use crate::scenario::{self, PoseRange, PositionRange, Scenario};

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
