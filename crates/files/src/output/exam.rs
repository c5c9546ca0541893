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
    for (p, model) in loaded.scenario.phantoms.iter().zip(&models) {
        let name = if p.mesh.is_some() {
            format!("{}-beads.csv", p.id)
        } else {
            format!("{}.csv", p.id)
        };
        let rel = format!("phantoms/{name}");
        if folder.exists(&rel) {
            let bytes = folder.read(&rel, MAX_TABLE_BYTES).map_err(|d| vec![d])?;
            beads.insert(
                p.id.clone(),
                parse_bead_table(&folder.path(&rel), &bytes, &model.markers)?,
            );
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

/// Parses the bead table read from `file` (`id,plate,role,x_mm,y_mm,z_mm,diameter_mm`), which
/// must list exactly the beads of the scenario's phantom (`markers`), each once, with finite
/// numbers: positions at most [`scenario::MAX_ABS`] mm from the origin's axes and
/// positive diameters. A received table cannot add beads the scenario does not have (5,000 copies
/// of one row made the correspondence search run for minutes).
fn parse_bead_table(
    file: &Path,
    bytes: &[u8],
    markers: &[phantom::Marker],
) -> Result<Vec<TableBead>, Vec<Diagnostic>> {
    use std::collections::HashSet;
    const HELP: &str = "columns: id,plate,role,x_mm,y_mm,z_mm,diameter_mm; one row per bead of the scenario's phantom, as rsasim wrote it";
    let expected: HashSet<&str> = markers.iter().map(|m| m.id.as_str()).collect();
    let mut seen: HashSet<String> = HashSet::new();
    let mut reader = csv::Reader::from_reader(bytes);
    let mut out = Vec::new();
    for (k, row) in reader.records().enumerate() {
        let bad = |what: String| {
            let mut d = Diagnostic::file_error(file, what).with_help(HELP);
            d.line_col = Some((k + 2, 1));
            vec![d]
        };
        let row = row.map_err(|e| bad(format!("malformed row: {e}")))?;
        let num = |i: usize, name: &str| {
            let v = row
                .get(i)
                .and_then(|v| v.parse::<f64>().ok())
                .ok_or_else(|| bad(format!("{name} (column {}) is not a number", i + 1)))?;
            if v.is_finite() && v.abs() <= scenario::MAX_ABS {
                Ok(v)
            } else {
                Err(bad(format!(
                    "{name} (column {}) is {v}, not finite within ±{:e} mm",
                    i + 1,
                    scenario::MAX_ABS
                )))
            }
        };
        let id = row.get(0).unwrap_or("").to_string();
        if !expected.contains(id.as_str()) {
            return Err(bad(format!(
                "bead `{}` is not a bead of the scenario's phantom",
                crate::diagnostic::cut(&id)
            )));
        }
        if !seen.insert(id.clone()) {
            return Err(bad(format!(
                "bead `{}` is listed twice",
                crate::diagnostic::cut(&id)
            )));
        }
        let diameter_mm = num(6, "diameter_mm")?;
        if diameter_mm <= 0.0 {
            return Err(bad(format!("diameter_mm is {diameter_mm}, not positive")));
        }
        out.push(TableBead {
            id,
            plate: row.get(1).unwrap_or("").to_string(),
            position_mm: DVec3::new(num(3, "x_mm")?, num(4, "y_mm")?, num(5, "z_mm")?),
            diameter_mm,
        });
    }
    if out.len() != markers.len() {
        let mut d = Diagnostic::file_error(
            file,
            format!(
                "lists {} bead(s); the scenario's phantom has {}",
                out.len(),
                markers.len()
            ),
        )
        .with_help(HELP);
        d.line_col = Some((out.len() + 2, 1));
        return Err(vec![d]);
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
