//! Command-line arguments: one struct per subcommand, read by its module under `commands/`, and
//! every enumerated flag a typed value ([`ValueEnum`]) mapped to the library's own type.

use std::ffi::OsStr;
use std::path::PathBuf;

use clap::builder::{RangedU64ValueParser, StringValueParser, TypedValueParser};
use clap::error::ErrorKind;
use clap::{Args, Parser, Subcommand, ValueEnum};
use rsasim::shard::ShardRequest;

/// rsasim: simulate Radio Stereometric Analysis X-ray scenes with known ground truth.
///
/// Run a scenario: `rsasim scenarios/biplanar.toml` writes images, truth.json and manifest.json
/// for every run of its protocol into out/<scenario name>/.
#[derive(Debug, Parser)]
#[command(
    name = "rsasim",
    version = rsasim::build_info::VERSION_LINE,
    args_conflicts_with_subcommands = true,
    subcommand_negates_reqs = true
)]
pub struct Cli {
    /// A subcommand; without one, rsasim runs the scenario given.
    #[command(subcommand)]
    pub command: Option<Command>,
    /// Running a scenario (the default command).
    #[command(flatten)]
    pub run: RunArgs,
}

/// Arguments of the default command: run a scenario.
#[derive(Debug, Args)]
pub struct RunArgs {
    /// The scenario file to run (TOML), e.g. scenarios/biplanar.toml.
    #[arg(required = true)]
    pub scenario: Option<PathBuf>,
    /// Output folder. Default: out/<scenario name>. It is written in a private staging folder
    /// beside it and swapped in only once complete; a lock file `.<name>.rsasim-lock` beside it
    /// keeps a second rsasim process out. A file or a symbolic link there is refused. With
    /// --shard, the folder that collects the shards (default out/<scenario name>-shards): the
    /// shard is written into DIR/shard-K-of-N/.
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Replace the output folder if it is an earlier rsasim output (its manifest.json says so) or
    /// empty; never the current folder or a parent of it, a folder holding the scenario or a mesh
    /// it reads, a link or a file. The old output is removed only after the new one is in place.
    #[arg(long)]
    pub force: bool,
    /// Blind layout: write the truth (every truth.json, the full scenario with its seed, and a
    /// manifest binding the images folder by hash) into DIR, and into --out only what the
    /// software under test may see: images, phantoms/ and the nominal set-up (no seed, no random
    /// ranges). DIR must lie outside the --out folder. Score with `rsasim evaluate OUT --truth DIR`.
    #[arg(long, value_name = "DIR")]
    pub truth_dir: Option<PathBuf>,
    /// Also write a picture of every image for people: `png` puts `<exposure>-<detector>.png`
    /// (8-bit, windowed to the 0.5–99.5th percentile, at most 1024 px on its longer side) beside
    /// each image, listed in the manifest. Previews are never evidence: score the TIFF/EXR.
    #[arg(long, value_name = "FORMAT")]
    pub preview: Option<Preview>,
    /// Write only shard K of N (K from 0 to N − 1, as Kubernetes' JOB_COMPLETION_INDEX and
    /// `sbatch --array=0-3` count) into OUT/shard-K-of-N/ with its own manifest: the runs at
    /// positions K, K + N, K + 2N, … of the protocol, byte for byte as a run without --shard
    /// writes them. `auto`: K and N from SLURM_ARRAY_TASK_ID with SLURM_ARRAY_TASK_MIN and
    /// SLURM_ARRAY_TASK_COUNT (or _MAX), or from JOB_COMPLETION_INDEX with --shard-count. A
    /// folder already holding this complete shard (same scenario, build and shard; every file
    /// verified) is left as it is. Join the shards with `rsasim merge`.
    #[arg(long, value_name = "K/N|auto", value_parser = ShardRequest::parse, conflicts_with = "truth_dir")]
    pub shard: Option<ShardRequest>,
    /// The number of shards N for `--shard auto` in a Kubernetes Indexed Job (its
    /// .spec.completions, which Kubernetes does not export); with SLURM or K/N it must agree.
    #[arg(long, value_name = "N", requires = "shard", value_parser = RangedU64ValueParser::<usize>::new().range(1..))]
    pub shard_count: Option<usize>,
    /// What the scenario may read and use beyond the defaults.
    #[command(flatten)]
    pub allow: AllowArgs,
}

/// Flags that widen what a scenario may read and use (run, validate, expand).
#[derive(Debug, Clone, Args)]
pub struct AllowArgs {
    /// A folder, besides the scenario file's own, that mesh files and the glTF buffers and
    /// images they reference may be read from (repeatable). Nothing outside is read.
    #[arg(long = "allow-dir", value_name = "DIR")]
    pub allow_dir: Vec<PathBuf>,
    /// Lift the caps on runs, pixels per image, bytes on disk and memory (see the manual,
    /// docs/src/reference/limits.md); the 4 GiB limit of a classic TIFF file still applies.
    #[arg(long)]
    pub allow_large: bool,
}

impl From<AllowArgs> for rsasim::simulate::Allowances {
    fn from(a: AllowArgs) -> Self {
        rsasim::simulate::Allowances {
            dirs: a.allow_dir,
            large: a.allow_large,
        }
    }
}

/// `rsasim evaluate`'s default confidence level (also `rsasim sweep --evaluate`'s).
pub const DEFAULT_CONFIDENCE: f64 = 0.95;

/// `rsasim evaluate`'s default report formats (also `rsasim sweep --evaluate`'s).
pub const DEFAULT_FORMATS: &str = "md,csv,tex,html";

/// The subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Check a scenario (syntax, values, mesh files, geometry of every run) and write nothing.
    Validate(ValidateArgs),
    /// Print every concrete run (poses, seeds, noise level) as JSON, in the box frame.
    Expand(ExpandArgs),
    /// Write one self-contained HTML page that shows the scenario in 3D before it is run: sources,
    /// detectors, calibration box, meshes and beads of the first run (drag to turn), each
    /// object's random range as a shaded box, the beam cones, the first run's images as
    /// thumbnails and the check's warnings placed on the objects. Not the run option
    /// `--preview png`, which writes a PNG beside every image of a run.
    Scene(SceneArgs),
    /// Score a software's results against the truth by ISO 5725 (trueness ± precision) and write
    /// the paper's tables as Markdown, CSV, LaTeX and a self-contained HTML report. On a sweep
    /// folder: every point's report, then the sweep's summary (sweep_summary.csv and
    /// sweep_summary.html in DIR/sweep-report/, or --report).
    Evaluate(EvaluateArgs),
    /// Check an output folder against its manifest.json: every listed file present, a regular
    /// file, of the recorded size and SHA-256; the manifest's own hash; files present but not
    /// listed. Prints one line per problem and a summary; exit 0 when everything verifies, 2 when
    /// anything does not. Given a truth folder of the blind layout, it also checks the images
    /// folder bound to it (found beside it, or given with --images).
    Verify(VerifyArgs),
    /// Run rsasim's reference RSA program on an output folder: calibrate every beamline from the
    /// box beads, find each model from its beads, and write
    /// measured-rsasim-<calibration>-<model>.json into every run folder (never over another
    /// software's results). It reads only what a real RSA program has: images, nominal set-up,
    /// phantoms/ (never truth.json). On a sweep folder: every point's output folder in turn.
    Reconstruct(ReconstructArgs),
    /// Write an output folder as the files XMALab or Autoscoper open, with the exam's known
    /// calibration: per run, a MayaCam 2.0 camera per detector (and DLT-11 coefficients, the box as
    /// XMALab's calibration object and the model beads' reference coordinates for XMALab; a trial
    /// `.cfg` per exposure for Autoscoper), the images as 16-bit TIFF sequences and the model
    /// meshes (OBJ for XMALab, STL for Autoscoper). DEST must be a new folder; it is written
    /// completely or not at all, and never inside OUT.
    Export(ExportArgs),
    /// Write the pinhole camera of a beamline in three forms: MayaCam 2.0 (XMALab, Autoscoper),
    /// DLT-11 (XMALab's and DLTdv's convention: 1-based pixels, origin bottom-left) and OpenCV
    /// K, R, t as JSON (`image_size_px`, `K`, `R`, `t_mm`: pixels 0-based from the top-left).
    /// The beamline is a source and the four outer corners of the image (`--source-mm`,
    /// `--corners-mm`, `--pixels`), every detector of a scenario's nominal set-up, or every
    /// detector of one run of an output folder (`OUT --run ID`, from its verified truth). Every
    /// form describes the image flipped top to bottom against rsasim's, as `rsasim export`
    /// writes it. Printed, or written into a new folder with --dir.
    Camera(CameraArgs),
    /// Join the shard folders of one scenario (written by `rsasim SCENARIO --shard K/N`) into
    /// one output folder, byte for byte the folder a run without --shard writes. Every shard is
    /// checked first: its manifest's own hash, the same scenario, seed, build and number of
    /// shards, no shard missing or given twice, no file added or changed (every file's SHA-256
    /// is checked as it is placed); any problem is an error (exit 2) and nothing is written.
    Merge(MergeArgs),
    /// Run a parameter sweep: expand the sweep file (a base scenario and the values of some of its
    /// keys, as a grid or zipped) into one standalone scenario per point, check them all, write
    /// them into DIR/points/ and run each into DIR/<point id>/ as `rsasim POINT.toml --out
    /// DIR/<point id>` would. Every point shares the base scenario's seed (common random numbers)
    /// unless the sweep varies `seed`. Run again on the same DIR, a stopped sweep resumes: complete
    /// points are kept, missing ones run. On a cluster: one `--shard K/N` task per shard, then
    /// `--merge`.
    Sweep(SweepArgs),
    /// Print a JSON Schema: scenario (default), truth, measured, manifest, study or migration_measured.
    Schema(SchemaArgs),
    /// Print materials' attenuation: density, composition by mass, absorption edges (1–200 keV)
    /// and, at each energy asked, μ/ρ (cm²/g) and μ (1/mm). A name is a shipped material, one of
    /// the scenario's own (`--scenario`) or a chemical symbol (the pure element at its density).
    Material(MaterialArgs),
    /// Print the beam of an attenuation-mode scenario: the spectrum after the tube's filtration
    /// (mean energy, first and second half-value layers in mm Al, photons and air kerma per mAs
    /// at 1000 mm), the bins traced for the images, the absorption edges of the materials in the
    /// beam, and each material's transmission at a thickness as the detector weighs it, over the
    /// traced bins and over every bin. Optionally writes the spectrum as TSV and as an SVG plot.
    Spectrum(SpectrumArgs),
}

/// Arguments of `rsasim material`.
#[derive(Debug, Args)]
pub struct MaterialArgs {
    /// Material names, e.g. tantalum cocr_f75 W.
    #[arg(required = true, value_name = "NAME")]
    pub names: Vec<String>,
    /// Photon energies, keV (1 to 200), comma-separated.
    #[arg(
        long,
        value_name = "KEV,…",
        value_delimiter = ',',
        default_value = "15,20,30,40,50,60,70,80,100,150"
    )]
    pub energies_kev: Vec<f64>,
    /// A scenario whose `[materials]` may be named too.
    #[arg(long, value_name = "FILE")]
    pub scenario: Option<PathBuf>,
    /// Print JSON instead of a table.
    #[arg(long)]
    pub json: bool,
}

/// Arguments of `rsasim spectrum`.
#[derive(Debug, Args)]
pub struct SpectrumArgs {
    /// The scenario file (attenuation mode).
    pub scenario: PathBuf,
    /// Thicknesses to give transmissions for: `MATERIAL=MM` (repeatable, or comma-separated; a
    /// material may be named with several), e.g. tantalum=0.5,tantalum=1,soft_tissue=100,W=0.5;
    /// a bare number applies to every material of the scene not named. Default: 1 mm of every
    /// material of the scene.
    #[arg(long, value_name = "[MATERIAL=]MM", value_delimiter = ',')]
    pub thickness_mm: Vec<String>,
    /// Also write the spectrum (every bin, before and after filtration, and the detector's
    /// absorption) as tab-separated text into FILE.
    #[arg(long, value_name = "FILE")]
    pub tsv: Option<PathBuf>,
    /// Also write a plot of the spectrum (SVG) into FILE.
    #[arg(long, value_name = "FILE")]
    pub svg: Option<PathBuf>,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
    /// What the scenario may read and use beyond the defaults.
    #[command(flatten)]
    pub allow: AllowArgs,
}

/// Arguments of `rsasim validate`.
#[derive(Debug, Args)]
pub struct ValidateArgs {
    /// The scenario file to check.
    pub scenario: PathBuf,
    /// What the scenario may read and use beyond the defaults.
    #[command(flatten)]
    pub allow: AllowArgs,
}

/// Arguments of `rsasim expand`.
#[derive(Debug, Args)]
pub struct ExpandArgs {
    /// The scenario file to expand.
    pub scenario: PathBuf,
    /// What the scenario may read and use beyond the defaults.
    #[command(flatten)]
    pub allow: AllowArgs,
}

/// Arguments of `rsasim scene`.
#[derive(Debug, Args)]
pub struct SceneArgs {
    /// The scenario file to show.
    pub scenario: PathBuf,
    /// The page file. Default: out/<scenario name>-scene.html. An existing file is
    /// replaced only when it is an earlier page of `rsasim scene`.
    #[arg(long, value_name = "FILE")]
    pub out: Option<PathBuf>,
    /// Leave out the thumbnails of the first run's images (making them simulates that run
    /// in a temporary folder).
    #[arg(long)]
    pub no_images: bool,
    /// What the scenario may read and use beyond the defaults.
    #[command(flatten)]
    pub allow: AllowArgs,
}

/// Arguments of `rsasim evaluate`.
#[derive(Debug, PartialEq, Args)]
pub struct EvaluateArgs {
    /// The output folder of a simulation (it holds manifest.json, scenario.toml and runs/), or
    /// a sweep folder (it holds sweep.json).
    pub out: PathBuf,
    /// File name of the results in every run folder (schemas/measured.schema.json). Default:
    /// measured.json if present, else the one measured*.json name the run folders hold
    /// (e.g. measured-rsasim-dlt-markers.json); several names are an error listing them. A
    /// name ending in .csv is read as XMALab's export of that run's trial: rigid-body
    /// transformations (bodies named after phantoms), 3D points or 2D points (markers named
    /// after beads; 2D points are triangulated with the exported true cameras). A name ending
    /// in .tra is read as Autoscoper's tracking of that run's trial: <exposure>_<phantom>.tra
    /// (one volume) or <exposure>.tra (every volume of the trial), matrices in row or column
    /// order or xyzypr.
    #[arg(long, value_name = "FILE_NAME", conflicts_with = "csv")]
    pub measured: Option<String>,
    /// Look for each run's results file in DIR/<run id>/ instead of OUT/runs/<run id>/, e.g.
    /// the folder `rsasim export` wrote, where XMALab's exports or Autoscoper's tracking were
    /// saved. A sequence's XMALab or Autoscoper file is DIR/<sequence id>/<name>, one for the
    /// sequence's trial: line (data row) k is its k-th frame.
    #[arg(long, value_name = "DIR", requires = "measured")]
    pub results_in: Option<PathBuf>,
    /// XMALab's 2D points: the y axis they were exported with, `down` (XMALab's default) or
    /// `up` (its "y axis up (Matlab)" option: y counted from the bottom row). The file does
    /// not say it.
    #[arg(
        long,
        value_name = "DIRECTION",
        default_value = "down",
        requires = "measured"
    )]
    pub xmalab_2d_y_axis: XmalabYAxis,
    /// XMALab's 2D points: the number of the first pixel they were exported with, 0
    /// (XMALab's default) or 1 (its "start coordinates at 1 (Matlab)" option). The file does
    /// not say it.
    #[arg(long, value_name = "N", default_value = "0", requires = "measured")]
    pub xmalab_2d_start_at: XmalabFirstPixel,
    /// Read every run's results from one CSV long table instead (columns in the manual, docs/src/guide/scoring.md).
    #[arg(long, value_name = "FILE")]
    pub csv: Option<PathBuf>,
    /// Confidence level of τ, in (0, 1).
    #[arg(long, default_value_t = DEFAULT_CONFIDENCE, value_name = "LEVEL")]
    pub confidence: f64,
    /// One- or two-sided τ; the paper's τ = 1.73 at N = 20 is one-sided 95 %.
    #[arg(long, default_value = "one")]
    pub sided: Sided,
    /// Report formats, comma-separated: md, csv, tex, html, pdf. pdf prints the HTML report
    /// with a headless browser: $RSASIM_BROWSER, else chromium, chromium-browser or
    /// google-chrome on PATH (none found: exit 2 before anything is written).
    #[arg(
        long,
        default_value = DEFAULT_FORMATS,
        value_delimiter = ',',
        value_name = "LIST",
        value_parser = ReportFormatParser
    )]
    pub format: Vec<ReportFormat>,
    /// The MTPM each model's MTPM cells are compared with, in mm: a cell whose upper end
    /// T + P exceeds it is marked. Default 0.2 (continuous migration of a knee prosthesis
    /// between one and two years that predicts loosening).
    #[arg(long, default_value_t = rsasim::evaluate::DEFAULT_MTPM_THRESHOLD_MM, value_name = "MM")]
    pub mtpm_threshold_mm: f64,
    /// The true source position the sources are scored against: `geometric` (the focal
    /// spot's centre, `position_mm`) or `effective` (its intensity-weighted centre,
    /// `effective_position_mm`, where the truth has one: what a calibration of the images
    /// finds). The report says which.
    #[arg(long, value_name = "WHICH", default_value = "geometric")]
    pub source_truth: SourceTruthArg,
    /// Folder the reports are written to. Default: OUT/report-<results file stem>, e.g.
    /// OUT/report-measured-rsasim-dlt-markers, so reports of two softwares never collide.
    /// On a sweep folder: the summary's folder (default DIR/sweep-report).
    #[arg(long, value_name = "DIR")]
    pub report: Option<PathBuf>,
    /// The truth folder of a blind layout (written by `rsasim SCENARIO --truth-dir DIR`); OUT
    /// is then its images folder. Both manifests and the binding between them are verified.
    #[arg(long, value_name = "DIR")]
    pub truth: Option<PathBuf>,
    /// Clinical studies: a CSV of relative motions per patient, follow-up exam and implant
    /// segment (header patient,exam,segment,tx_mm,ty_mm,tz_mm,rx_deg,ry_deg,rz_deg,mtpm_mm)
    /// to score instead of the per-exam results.
    #[arg(long, value_name = "FILE")]
    pub migration_csv: Option<PathBuf>,
    /// Clinical studies: a marker whose leave-one-out residual between exams exceeds this
    /// (mm) is loose: excluded when the migration is computed from per-exam results, and the
    /// loose-marker table lists the markers that truly moved more. Default 0.3.
    #[arg(long, default_value_t = rsasim::migration::DEFAULT_STABILITY_THRESHOLD_MM, value_name = "MM")]
    pub stability_threshold_mm: f64,
    /// Clinical studies: also report the 99 % double-exam limits (mean ± 2.576·SD and
    /// t(0.995, n−1)·SD).
    #[arg(long)]
    pub limits_99: bool,
}

/// Arguments of `rsasim verify`.
#[derive(Debug, Args)]
pub struct VerifyArgs {
    /// The output folder (or truth folder) to check.
    pub out: PathBuf,
    /// The images folder bound to the truth folder OUT, when it is not beside it under the
    /// name it was written with.
    #[arg(long, value_name = "DIR")]
    pub images: Option<PathBuf>,
}

/// Arguments of `rsasim reconstruct`.
#[derive(Debug, Args)]
pub struct ReconstructArgs {
    /// The output folder of a simulation, or a sweep folder.
    pub out: PathBuf,
    /// How each beamline is calibrated from the box beads. dlt: normalised DLT on both facing
    /// plates, decomposition with the known pixel pitch, joint Levenberg–Marquardt fit of
    /// source and detector. selvik: the classic cage method (homography from the fiducial
    /// plate, focus from the control plate; not statistically optimal), for comparison.
    #[arg(long, default_value = "dlt")]
    pub method: Calibration,
    /// How each model's pose is found. markers: marker-based RSA (triangulate the model's
    /// beads in two views, fit its bead table). silhouette: model-based RSA (fit the model
    /// mesh's projected outline to the edges of its shadow in every view; no beads needed).
    /// Default: markers for a model with beads, silhouette for a model without.
    #[arg(long, value_name = "METHOD")]
    pub model_method: Option<ModelMethod>,
    /// File name of the results in every run folder. Default:
    /// measured-rsasim-<calibration>-<model>.json, e.g. measured-rsasim-dlt-markers.json
    /// (`auto` for the model part when models use different methods by default).
    #[arg(long, value_name = "FILE_NAME")]
    pub measured: Option<String>,
    /// Replace a results file of that name even if another software wrote it (or it does not
    /// parse). rsasim's own earlier results are always replaced.
    #[arg(long)]
    pub overwrite: bool,
    /// Clinical studies (OUT holds study.json): a marker whose leave-one-out residual in the
    /// fit between an exam and the reference exam exceeds this (mm) is loose and excluded from
    /// the migration. Default 0.3.
    #[arg(long, default_value_t = rsasim::migration::DEFAULT_STABILITY_THRESHOLD_MM, value_name = "MM")]
    pub stability_threshold_mm: f64,
    /// How a bead's sub-pixel centre is measured in attenuation-mode images, after its
    /// intensity centroid. auto: a sphere's chord profile on images the set-up declares sharp
    /// (one ray per pixel centre from a point source, no PSF or MTF, no motion during a pulse),
    /// where a Gaussian pixel-locks; a circular Gaussian otherwise. gaussian, sphere: that
    /// profile on every image, for comparison (the results' `software` then names it). Binary
    /// images are measured by their pixels' covered fraction either way.
    #[arg(long, value_name = "PROFILE", default_value = "auto")]
    pub bead_centre: BeadCentre,
    /// DLT calibration: whether the beads of plates seen within 45° of edge-on are fitted
    /// (matched once a first calibration from the facing plates predicts them). auto: unless
    /// the plate itself is imaged (attenuation mode, a plate with a thickness), whose dense band
    /// along its beads shortens the measured source distance on blurred images (the book's
    /// Biases chapter). fit, skip: always, never, for comparison (the results' `software` then
    /// names it).
    #[arg(long, value_name = "CHOICE", default_value = "auto")]
    pub edge_on_plates: EdgeOnPlates,
}

/// Arguments of `rsasim export`.
#[derive(Debug, Args)]
pub struct ExportArgs {
    /// The output folder of a simulation (the ordinary layout, with truth.json in every run),
    /// or the images folder of a blind layout together with --truth.
    pub out: PathBuf,
    /// The truth folder of a blind layout (written by `rsasim SCENARIO --truth-dir DIR`); OUT
    /// is then its images folder. Both manifests and the binding between them are verified.
    #[arg(long, value_name = "DIR")]
    pub truth: Option<PathBuf>,
    /// The program to export for.
    #[arg(long)]
    pub to: ExportTarget,
    /// The new folder to write (one sub-folder per run; one per sequence, its frames as one
    /// trial).
    #[arg(long, value_name = "DEST")]
    pub dir: PathBuf,
    /// Export only this run (repeatable), e.g. --run n0-r00. For a sequence give its id, the
    /// run id without the frame (n0-r00 for n0-r00-f0000 …): it is exported whole, as one
    /// trial. Default: every run and sequence.
    #[arg(long = "run", value_name = "RUN_ID")]
    pub runs: Vec<String>,
    /// How dense matter (beads, implants, bone) looks in the exported images: `dark` (the
    /// default, what XMALab's default marker detection and Autoscoper's radiograph rendering
    /// expect) or `bright` (XMALab's frame specification then says `white`). Binary-mode and
    /// radiograph-polarity images show it bright, raw detector images dark; the export inverts
    /// (I_max − value) where they differ from the choice.
    #[arg(long, value_name = "SHADE", default_value = "dark")]
    pub dense_matter: DenseMatterArg,
    /// XMALab: write the calibration box as XMALab's calibration object (frame specification
    /// and four reference beads, for XMALab's own cube calibration). `when-possible` (default):
    /// in every run whose box has four beads XMALab can tell apart in every calibration view,
    /// on plates not seen edge-on and spanning a tetrahedron (other runs are named in a note);
    /// `required`: an error when a run has no such four; `none`: cameras only.
    #[arg(long, value_name = "WHEN", default_value = "when-possible")]
    pub calibration_object: CalibrationObjectArg,
    /// Autoscoper: the voxel size of the model volumes (isotropic), mm.
    #[arg(long, value_name = "MM", default_value_t = 0.5)]
    pub voxel_mm: f64,
    /// Cameras from the calibration a software measured (sources and detector poses of this
    /// results file in every run folder, e.g. measured-rsasim-dlt-markers.json) instead of
    /// the true calibration.
    #[arg(long, value_name = "FILE_NAME")]
    pub calibration_from: Option<String>,
}

/// Arguments of `rsasim camera`.
#[derive(Debug, Args)]
#[command(group(clap::ArgGroup::new("beamline").required(true).args(["input", "source_mm"])))]
pub struct CameraArgs {
    /// A scenario file (the cameras of its nominal set-up, no random draw), or an output folder
    /// with --run (the cameras of that run's truth).
    #[arg(value_name = "SCENARIO|OUT", conflicts_with_all = ["source_mm", "corners_mm", "pixels", "detector"])]
    pub input: Option<PathBuf>,
    /// The run of the output folder OUT whose true cameras are written, e.g. n0-r00.
    #[arg(long, value_name = "RUN_ID", requires = "input")]
    pub run: Option<String>,
    /// The focus position X,Y,Z, mm.
    #[arg(long, value_name = "X,Y,Z", allow_hyphen_values = true, requires_all = ["corners_mm", "pixels"])]
    pub source_mm: Option<String>,
    /// The four outer corners of the image, mm, in this order: the top-left corner of row 0
    /// (the outer corner of the first pixel), the end of row 0, the end of the last row, the
    /// start of the last row. Row 0 is the top row of the image as the camera sees it from the
    /// source; the corners must form a rectangle (within 1e-6 of its diagonal).
    #[arg(
        long,
        value_name = "x,y,z;x,y,z;x,y,z;x,y,z",
        allow_hyphen_values = true,
        requires = "source_mm"
    )]
    pub corners_mm: Option<String>,
    /// The image's columns and rows, W,H; the pixel pitch is each side's length over its count.
    #[arg(long, value_name = "W,H", requires = "source_mm")]
    pub pixels: Option<String>,
    /// The camera's name, for its files with --dir. Default: det1.
    #[arg(long, value_name = "ID", requires = "source_mm")]
    pub detector: Option<String>,
    /// Write a new folder DEST with <detector>_MayaCam.txt and <detector>_opencv.json per
    /// camera and dlt11.csv (11 rows, one column per camera), instead of printing them. It is
    /// written completely or not at all; an existing folder is refused.
    #[arg(long, value_name = "DEST")]
    pub dir: Option<PathBuf>,
    /// A folder, besides the scenario file's own, that its mesh files may be read from
    /// (repeatable).
    #[arg(long = "allow-dir", value_name = "DIR")]
    pub allow_dir: Vec<PathBuf>,
}

/// Arguments of `rsasim merge`.
#[derive(Debug, Args)]
pub struct MergeArgs {
    /// Every shard folder (all N, any order), e.g. out/knee-shards/shard-*.
    #[arg(required = true, value_name = "SHARD_DIR")]
    pub shards: Vec<PathBuf>,
    /// The merged output folder. Written like a run's output: staged beside it, swapped in
    /// when complete, under the same lock.
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// Replace OUT if it is an earlier rsasim output (the rules of a run's --force).
    #[arg(long)]
    pub force: bool,
    /// Copy the files. Default: hard-link them (no time, no space; the shard and the merged
    /// folder then share each file's bytes, which rsasim never changes in place), copying
    /// only where a link is impossible (another file system).
    #[arg(long)]
    pub copy: bool,
}

/// Arguments of `rsasim sweep`.
#[derive(Debug, Args)]
pub struct SweepArgs {
    /// The sweep file (TOML), e.g. scenarios/sweeps/tube_angle.toml.
    pub file: PathBuf,
    /// The sweep folder: new or empty, or the folder of an earlier run of the same sweep.
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// Then run the reference program (`rsasim reconstruct`, default methods) on every point
    /// and `rsasim evaluate DIR`: each point's report and the sweep's summary in
    /// DIR/sweep-report/ (sweep_summary.csv, sweep_summary.html).
    #[arg(long, conflicts_with = "no_run")]
    pub evaluate: bool,
    /// Write the sweep folder's point scenarios and index, and run nothing: e.g. to run each
    /// point as its own cluster job (`rsasim DIR/points/<id>.toml --out DIR/<id>`). A later
    /// `rsasim sweep` on the same folder runs only the points still missing.
    #[arg(long)]
    pub no_run: bool,
    /// Write only task K of N of the sweep (K from 0 to N − 1): one shard of every point, into
    /// DIR/shards/<point id>/shard-j-of-N/, byte for byte as `rsasim DIR/points/<point
    /// id>.toml --shard j/N` writes it. The tasks deal the runs of all points in sweep order
    /// round robin (run g of the whole sweep to task g mod N), so task K writes shard
    /// j = (K − runs before the point) mod N of each point. The tasks may run at once into one
    /// DIR on a shared file system: the sweep's own files are written once and checked by the
    /// others, each shard folder has its own lock. `auto`: K and N from SLURM or Kubernetes,
    /// as for a scenario's --shard. A finished shard is left as it is; a point already
    /// complete in DIR/<point id> needs none. Then `--merge`.
    #[arg(long, value_name = "K/N|auto", value_parser = ShardRequest::parse, conflicts_with_all = ["no_run", "evaluate", "merge"])]
    pub shard: Option<ShardRequest>,
    /// The number of shards N: for `--shard auto` in a Kubernetes Indexed Job (its
    /// .spec.completions); with --merge, which split to merge when a point's shard folder
    /// holds several.
    #[arg(long, value_name = "N", value_parser = RangedU64ValueParser::<usize>::new().range(1..))]
    pub shard_count: Option<usize>,
    /// Merge a sharded sweep: check every point's shards in DIR/shards/<point id>/ as
    /// `rsasim merge` checks them (a missing shard names its point and runs; any problem:
    /// exit 2, nothing written), then join each into DIR/<point id>/, byte for byte the
    /// folder an unsharded sweep writes (files hard-linked). Points already complete are
    /// kept. With --evaluate, then reconstruct and evaluate as an unsharded sweep.
    #[arg(long, conflicts_with = "no_run")]
    pub merge: bool,
    /// What the base scenario may read and use beyond the defaults (--allow-large also lifts
    /// the cap of 1000 points).
    #[command(flatten)]
    pub allow: AllowArgs,
}

/// Arguments of `rsasim schema`.
#[derive(Debug, Args)]
pub struct SchemaArgs {
    /// Which schema to print.
    #[arg(default_value = "scenario")]
    pub name: SchemaName,
    /// Instead of printing, write every schema as <DIR>/<name>.schema.json.
    #[arg(long, value_name = "DIR")]
    pub write_dir: Option<PathBuf>,
}

impl EvaluateArgs {
    /// `rsasim evaluate OUT` with every option at its default: what `rsasim sweep --evaluate`
    /// runs on the sweep folder.
    pub fn defaults(out: PathBuf) -> Self {
        EvaluateArgs {
            out,
            measured: None,
            results_in: None,
            csv: None,
            confidence: DEFAULT_CONFIDENCE,
            sided: Sided::One,
            format: DEFAULT_FORMATS
                .split(',')
                .map(|f| ReportFormat::from_str(f, false).expect("a default format"))
                .collect(),
            mtpm_threshold_mm: rsasim::evaluate::DEFAULT_MTPM_THRESHOLD_MM,
            source_truth: SourceTruthArg::Geometric,
            report: None,
            truth: None,
            migration_csv: None,
            stability_threshold_mm: rsasim::migration::DEFAULT_STABILITY_THRESHOLD_MM,
            limits_99: false,
            xmalab_2d_y_axis: XmalabYAxis::Down,
            xmalab_2d_start_at: XmalabFirstPixel::Zero,
        }
    }
}

// The enumerated flags. Their variants carry no doc comment: clap would show it in `--help`.

/// `--preview`: the picture written beside every image (only `png`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Preview {
    Png,
}

/// `evaluate --sided`: one- or two-sided τ ([`rsasim::evaluate::stats::Sided`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Sided {
    One,
    Two,
}

impl From<Sided> for rsasim::evaluate::stats::Sided {
    fn from(s: Sided) -> Self {
        match s {
            Sided::One => Self::One,
            Sided::Two => Self::Two,
        }
    }
}

/// `evaluate --format`: one report format ([`rsasim::evaluate::report::Format`]), spelled `md`
/// (or `markdown`), `csv`, `tex` (or `latex`), `html` or `pdf`, in any case.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ReportFormat {
    #[value(name = "md", alias = "markdown")]
    Markdown,
    Csv,
    #[value(name = "tex", alias = "latex")]
    Latex,
    Html,
    Pdf,
}

impl From<ReportFormat> for rsasim::evaluate::report::Format {
    fn from(f: ReportFormat) -> Self {
        match f {
            ReportFormat::Markdown => Self::Markdown,
            ReportFormat::Csv => Self::Csv,
            ReportFormat::Latex => Self::Latex,
            ReportFormat::Html => Self::Html,
            ReportFormat::Pdf => Self::Pdf,
        }
    }
}

/// `--format`'s parser: each name of the list trimmed and in any case (`md, HTML` is `md,html`);
/// any other name is refused with the library's message and nothing else (exit 2).
#[derive(Debug, Clone, Copy)]
struct ReportFormatParser;

impl TypedValueParser for ReportFormatParser {
    type Value = ReportFormat;

    fn parse_ref(
        &self,
        cmd: &clap::Command,
        arg: Option<&clap::Arg>,
        value: &OsStr,
    ) -> Result<ReportFormat, clap::Error> {
        let name = StringValueParser::new().parse_ref(cmd, arg, value)?;
        ReportFormat::from_str(name.trim(), true).map_err(|_| {
            let why = rsasim::evaluate::report::ParseFormatError(name);
            // A raw message is printed as `error: <message>`, without clap's usage lines.
            clap::Error::raw(ErrorKind::InvalidValue, format!("--format: {why}\n"))
        })
    }
}

/// `reconstruct --method`: how each beamline is calibrated ([`rsasim::reconstruct::Method`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Calibration {
    Dlt,
    Selvik,
}

impl From<Calibration> for rsasim::reconstruct::Method {
    fn from(m: Calibration) -> Self {
        match m {
            Calibration::Dlt => Self::Dlt,
            Calibration::Selvik => Self::Selvik,
        }
    }
}

/// `reconstruct --model-method`: how each model's pose is found
/// ([`rsasim::reconstruct::ModelMethod`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ModelMethod {
    Markers,
    Silhouette,
}

impl From<ModelMethod> for rsasim::reconstruct::ModelMethod {
    fn from(m: ModelMethod) -> Self {
        match m {
            ModelMethod::Markers => Self::Markers,
            ModelMethod::Silhouette => Self::Silhouette,
        }
    }
}

/// `reconstruct --bead-centre`: the profile fitted to a bead in attenuation-mode images
/// ([`rsasim::reconstruct::beads::Centre`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum BeadCentre {
    Auto,
    Gaussian,
    Sphere,
}

impl From<BeadCentre> for Option<rsasim::reconstruct::beads::Centre> {
    fn from(c: BeadCentre) -> Self {
        use rsasim::reconstruct::beads::Centre;
        match c {
            BeadCentre::Auto => None,
            BeadCentre::Gaussian => Some(Centre::GaussianFit),
            BeadCentre::Sphere => Some(Centre::SphereFit),
        }
    }
}

/// `reconstruct --edge-on-plates`: whether a DLT fits the beads of plates seen edge-on
/// ([`rsasim::reconstruct::EdgeOnPlates`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum EdgeOnPlates {
    Auto,
    Fit,
    Skip,
}

impl From<EdgeOnPlates> for rsasim::reconstruct::EdgeOnPlates {
    fn from(c: EdgeOnPlates) -> Self {
        match c {
            EdgeOnPlates::Auto => Self::Auto,
            EdgeOnPlates::Fit => Self::Fit,
            EdgeOnPlates::Skip => Self::Skip,
        }
    }
}

/// `export --dense-matter`: how dense matter looks in the exported images
/// ([`rsasim::interop::export::DenseMatter`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum DenseMatterArg {
    /// Beads and implants dark on a bright background.
    Dark,
    /// Beads and implants bright on a dark background.
    Bright,
}

impl From<DenseMatterArg> for rsasim::interop::export::DenseMatter {
    fn from(d: DenseMatterArg) -> Self {
        match d {
            DenseMatterArg::Dark => Self::Dark,
            DenseMatterArg::Bright => Self::Bright,
        }
    }
}

/// `export --calibration-object` ([`rsasim::interop::export::CalibrationObject`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum CalibrationObjectArg {
    /// In every run whose box has four reference beads by rule.
    WhenPossible,
    /// In every run, or an error.
    Required,
    /// Never.
    None,
}

impl From<CalibrationObjectArg> for rsasim::interop::export::CalibrationObject {
    fn from(c: CalibrationObjectArg) -> Self {
        match c {
            CalibrationObjectArg::WhenPossible => Self::WhenPossible,
            CalibrationObjectArg::Required => Self::Required,
            CalibrationObjectArg::None => Self::Omit,
        }
    }
}

/// `export --to`: the program exported for ([`rsasim::interop::export::Target`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ExportTarget {
    Xmalab,
    Autoscoper,
}

impl From<ExportTarget> for rsasim::interop::export::Target {
    fn from(t: ExportTarget) -> Self {
        match t {
            ExportTarget::Xmalab => Self::Xmalab,
            ExportTarget::Autoscoper => Self::Autoscoper,
        }
    }
}

/// `evaluate --source-truth` ([`rsasim::evaluate::SourceTruth`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum SourceTruthArg {
    Geometric,
    Effective,
}

impl From<SourceTruthArg> for rsasim::evaluate::SourceTruth {
    fn from(s: SourceTruthArg) -> Self {
        match s {
            SourceTruthArg::Geometric => Self::Geometric,
            SourceTruthArg::Effective => Self::Effective,
        }
    }
}

/// `evaluate --xmalab-2d-y-axis`: the y axis of XMALab's 2-D point export
/// ([`rsasim::interop::xmalab_points2d::YAxis`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum XmalabYAxis {
    Down,
    Up,
}

impl From<XmalabYAxis> for rsasim::interop::xmalab_points2d::YAxis {
    fn from(y: XmalabYAxis) -> Self {
        match y {
            XmalabYAxis::Down => Self::Down,
            XmalabYAxis::Up => Self::Up,
        }
    }
}

/// `evaluate --xmalab-2d-start-at`: the first pixel's number in XMALab's 2-D point export
/// ([`rsasim::interop::xmalab_points2d::FirstPixel`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum XmalabFirstPixel {
    #[value(name = "0")]
    Zero,
    #[value(name = "1")]
    One,
}

impl From<XmalabFirstPixel> for rsasim::interop::xmalab_points2d::FirstPixel {
    fn from(f: XmalabFirstPixel) -> Self {
        match f {
            XmalabFirstPixel::Zero => Self::Zero,
            XmalabFirstPixel::One => Self::One,
        }
    }
}

/// `schema NAME`: one of the schemas of [`rsasim::output::schemas`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum SchemaName {
    Scenario,
    Truth,
    Measured,
    Manifest,
    Study,
    #[value(name = "migration_measured")]
    MigrationMeasured,
}

impl SchemaName {
    /// The name [`rsasim::output::schemas`] lists it under: its name on the command line.
    pub fn name(self) -> String {
        let value = self.to_possible_value().expect("no name is skipped");
        value.get_name().to_owned()
    }
}

#[cfg(test)]
mod tests {
    use clap::CommandFactory;

    use super::*;

    #[test]
    fn the_arguments_are_consistent() {
        Cli::command().debug_assert();
    }

    #[test]
    fn evaluate_defaults_are_those_of_the_command_line() {
        let parsed = Cli::try_parse_from(["rsasim", "evaluate", "some/out"]).unwrap();
        let Some(Command::Evaluate(args)) = parsed.command else {
            panic!("not evaluate: {parsed:?}")
        };
        assert_eq!(args, EvaluateArgs::defaults(PathBuf::from("some/out")));
    }

    #[test]
    fn every_schema_name_is_a_schema() {
        let schemas: Vec<&str> = rsasim::output::schemas().iter().map(|(n, _)| *n).collect();
        let names: Vec<String> = SchemaName::value_variants()
            .iter()
            .map(|s| s.name())
            .collect();
        assert_eq!(names, schemas);
    }

    #[test]
    fn report_formats_are_read_as_the_library_reads_them() {
        use rsasim::evaluate::report::Format;
        let cmd = Cli::command();
        for name in [
            "md", "Markdown", " html", "LaTeX", "tex", "csv", "PDF", "docx", "",
        ] {
            let ours = ReportFormatParser
                .parse_ref(&cmd, None, OsStr::new(name))
                .map(Format::from)
                .map_err(|e| e.to_string());
            let theirs = name
                .parse::<Format>()
                .map_err(|e| format!("error: --format: {e}\n"));
            assert_eq!(ours, theirs, "{name:?}");
        }
    }
}
