//! Writes a PNG preview of one or more detector images (side by side), e.g. for the manual's figures.
//!
//! ```text
//! cargo run --release --example preview -- OUT.png MAX_SIDE_PX RUN_DIR/STEM [RUN_DIR/STEM …]
//! cargo run --release --example preview -- /tmp/cal.png 720 out/x/runs/n0-r00/calibration-det1
//! ```
//!
//! Each `RUN_DIR/STEM` names `STEM.tiff` (or else `STEM.exr`) in `RUN_DIR`. Previews are for
//! people, never evidence (see `rsasim::output::preview`).

use std::path::Path;
use std::process::ExitCode;

use rsasim::output::decode::read_image;
use rsasim::output::preview::side_by_side;

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (Some(out), Some(Ok(max_side)), images) = (
        args.first(),
        args.get(1).map(|s| s.parse::<u32>()),
        args.get(2..).unwrap_or_default(),
    ) else {
        eprintln!("usage: preview OUT.png MAX_SIDE_PX RUN_DIR/STEM [RUN_DIR/STEM …]");
        return ExitCode::from(2);
    };
    if images.is_empty() {
        eprintln!("usage: preview OUT.png MAX_SIDE_PX RUN_DIR/STEM [RUN_DIR/STEM …]");
        return ExitCode::from(2);
    }
    let mut loaded = Vec::new();
    for image in images {
        let path = Path::new(image);
        let (dir, stem) = (
            path.parent().unwrap_or(Path::new(".")),
            path.file_name().and_then(|s| s.to_str()).unwrap_or(""),
        );
        match read_image(dir, stem) {
            Ok(img) => loaded.push(img),
            Err(e) => {
                eprintln!("error: {e}");
                return ExitCode::from(2);
            }
        }
    }
    let views: Vec<(&[u16], u32, u32)> = loaded
        .iter()
        .map(|(w, h, p)| (p.as_slice(), *w, *h))
        .collect();
    if let Err(e) = std::fs::write(out, side_by_side(&views, max_side)) {
        eprintln!("error: cannot write {out}: {e}");
        return ExitCode::FAILURE;
    }
    ExitCode::SUCCESS
}
