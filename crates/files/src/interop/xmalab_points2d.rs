//! The options of XMALab's 2-D point export, and how `rsasim evaluate` undoes them.
//!
//! XMALab writes 2-D points in `Trial::save2dPoints` (src/core/Trial.cpp of XROMMPackages/xmalab,
//! 2.2.7), with three options of its export dialog (src/ui/ui-files/PointImportExportDialog.ui):
//!
//! - "start coordinates at 1 (Matlab)" (`offset1`): x + 1 and y + 1 are written.
//! - "y axis up (Matlab)" (`yinvert`): y is written as H − y − 1 (H the image height), before
//!   the + 1 of the first option.
//! - "cam offset columns (Matlab xromm tools and subsequence)" (`offsetCols`): every row starts
//!   with one column per camera holding `0`, and the header with `cam<j>_offset` for
//!   j = 0 … C − 1, written with no comma between them nor before the first marker's column:
//!   `cam0_offsetcam1_offsetK1_cam1_X,K1_cam1_Y,…` over rows `0,0,…`. The header thus has C
//!   cells fewer than the rows. The same names separated by commas (what XMALab's own reader,
//!   `Trial::load2dPoints`, counts on) are read too; the values are ignored, as that reader does.
//!
//! Nothing in the file tells the first two options apart from the defaults (0-based, y down),
//! so the user states them ([`PixelOptions`]); the third is read from the header.

/// The direction of XMALab's 2-D y axis in an export.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum YAxis {
    /// "y axis down": from the top row (XMALab's default).
    #[default]
    Down,
    /// "y axis up (Matlab)": from the bottom row.
    Up,
}

/// The number of the first pixel in an export.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum FirstPixel {
    /// "start coordinates at 0" (XMALab's default).
    #[default]
    Zero,
    /// "start coordinates at 1 (Matlab)".
    One,
}

/// How the pixels of a 2-D point export were written.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct PixelOptions {
    /// Where y is measured from.
    pub y_axis: YAxis,
    /// The number of the first pixel.
    pub first_pixel: FirstPixel,
}

impl PixelOptions {
    /// XMALab's pixel (0-based, y down: OpenCV's) of a value exported with these options from
    /// an image `height` rows high; the inverse of `Trial::save2dPoints`.
    pub fn to_xmalab(self, xy: [f64; 2], height: u32) -> [f64; 2] {
        let [mut x, mut y] = xy;
        if self.first_pixel == FirstPixel::One {
            x -= 1.0;
            y -= 1.0;
        }
        if self.y_axis == YAxis::Up {
            y = f64::from(height) - y - 1.0;
        }
        [x, y]
    }

    /// The options as `rsasim evaluate` flags, for messages.
    pub fn flags(self) -> String {
        let y = match self.y_axis {
            YAxis::Down => "down",
            YAxis::Up => "up",
        };
        let first = match self.first_pixel {
            FirstPixel::Zero => 0,
            FirstPixel::One => 1,
        };
        format!("--xmalab-2d-y-axis {y} --xmalab-2d-start-at {first}")
    }
}

/// The offset columns found at the start of a header.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct OffsetColumns {
    /// Their number: one per camera, the leading cells of every row.
    pub count: usize,
    /// Bytes of the header they take, with their commas.
    pub bytes: usize,
}

/// The refusal of a header: its 1-based character column, the message and a help.
pub type HeaderError = (usize, String, String);

/// The offset columns that start `header` (see the module docs), `None` when it has none;
/// refused when they are not `cam0_offset` … `cam<C−1>_offset` for the run's `cameras`.
pub fn offset_columns(header: &str, cameras: usize) -> Result<Option<OffsetColumns>, HeaderError> {
    let help = || {
        format!(
            "XMALab writes the offset columns of {cameras} camera(s) as {}; export again, or without \"cam offset columns\"",
            (0..cameras)
                .map(|j| format!("cam{j}_offset"))
                .collect::<String>()
        )
    };
    let mut at = 0;
    let mut count = 0;
    while let Some(rest) = header[at..].strip_prefix(&format!("cam{count}_offset")) {
        at = header.len() - rest.len();
        at += usize::from(rest.starts_with(','));
        count += 1;
    }
    let rest = &header[at..];
    let first_cell = rest.split(',').next().unwrap_or_default();
    if first_cell.to_ascii_lowercase().contains("offset") {
        return Err((
            header[..at].chars().count() + 1,
            format!(
                "`{}` is no offset column XMALab writes",
                crate::diagnostic::cut(first_cell)
            ),
            help(),
        ));
    }
    if count == 0 {
        return Ok(None);
    }
    if count != cameras {
        return Err((
            1,
            format!("{count} offset column(s) for the run's {cameras} camera(s)"),
            help(),
        ));
    }
    Ok(Some(OffsetColumns { count, bytes: at }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn options_undo_what_xmalab_writes_by_hand() {
        // Trial::save2dPoints, H = 480: y up writes 480 − 100 − 1 = 379; start at 1 adds 1.
        let xy = [20.0, 100.0];
        let written = |y_axis, first_pixel| {
            let o = PixelOptions {
                y_axis,
                first_pixel,
            };
            (o, o.to_xmalab(xy, 480))
        };
        assert_eq!(written(YAxis::Down, FirstPixel::Zero).1, [20.0, 100.0]);
        let (o, _) = written(YAxis::Up, FirstPixel::Zero);
        assert_eq!(o.to_xmalab([20.0, 379.0], 480), xy);
        let (o, _) = written(YAxis::Down, FirstPixel::One);
        assert_eq!(o.to_xmalab([21.0, 101.0], 480), xy);
        let (o, _) = written(YAxis::Up, FirstPixel::One);
        assert_eq!(o.to_xmalab([21.0, 380.0], 480), xy);
    }

    #[test]
    fn offset_columns_as_xmalab_writes_them() {
        let h = "cam0_offsetcam1_offsetK1_cam1_X,K1_cam1_Y";
        assert_eq!(
            offset_columns(h, 2),
            Ok(Some(OffsetColumns {
                count: 2,
                bytes: 22
            }))
        );
        let h = "cam0_offset,cam1_offset,K1_cam1_X";
        assert_eq!(offset_columns(h, 2).unwrap().unwrap().bytes, 24);
        assert_eq!(offset_columns("K1_cam1_X,K1_cam1_Y", 2), Ok(None));
        let e = offset_columns("cam0_offsetK1_cam1_X", 2).unwrap_err();
        assert_eq!(e.0, 1);
        assert!(e.1.contains("1 offset column(s)") && e.2.contains("cam0_offsetcam1_offset"));
        let e = offset_columns("cam0_offsetcam2_offsetK1_cam1_X", 2).unwrap_err();
        assert_eq!(e.0, 12, "{e:?}");
        let e = offset_columns("cam1_offsetcam2_offsetK1_cam1_X", 2).unwrap_err();
        assert_eq!(e.0, 1);
        let e = offset_columns("Cam0_Offset,K1_cam1_X", 2).unwrap_err();
        assert_eq!(e.0, 1);
    }
}
