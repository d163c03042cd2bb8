//! Log-log figures (plotters): Allan deviation with confidence bands and the fitted noise
//! terms, PSD with slope lines. SVG or PNG by the file's extension; text is drawn with an
//! embedded DejaVu Sans, so no system fonts are needed.

use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;
use std::sync::Once;

/// One curve on a panel; `band` is an optional (lower, upper) envelope drawn shaded.
#[derive(Debug, Clone)]
pub struct Line {
    pub label: String,
    pub x: Vec<f64>,
    pub y: Vec<f64>,
    pub band: Option<(Vec<f64>, Vec<f64>)>,
    /// Palette index; lines sharing a colour (a curve and its fit) use the same index.
    pub color: usize,
    pub dashed: bool,
}

/// One log-log chart.
#[derive(Debug, Clone)]
pub struct Panel {
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    pub lines: Vec<Line>,
}

/// A row of panels under a title (one per sensor: gyroscope, accelerometer).
#[derive(Debug, Clone)]
pub struct Figure {
    pub title: String,
    pub panels: Vec<Panel>,
}

#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    #[error("{path}: plots are written as .svg or .png")]
    Format { path: String },
    #[error("{path}: {message}")]
    Draw { path: String, message: String },
    #[error("nothing to plot")]
    Empty,
}

const PANEL_W: u32 = 640;
const PANEL_H: u32 = 480;
const TITLE_H: u32 = 36;
const PALETTE: [RGBColor; 7] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(148, 103, 189),
    RGBColor(255, 127, 14),
    RGBColor(140, 86, 75),
    RGBColor(23, 190, 207),
];

fn register_font() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        // The embedded font is valid TrueType; if registration failed, text would be missing
        // but the plot would still be drawn, so the error is not fatal.
        let _ = plotters::style::register_font(
            "sans-serif",
            FontStyle::Normal,
            dejavu::sans::regular(),
        );
    });
}

/// The image format `path` names by its extension (`svg` or `png`, lower case), or the
/// error: checked before the work whose figures it would hold.
pub fn check_format(path: &Path) -> Result<String, PlotError> {
    path.extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .filter(|e| e == "svg" || e == "png")
        .ok_or_else(|| PlotError::Format {
            path: path.display().to_string(),
        })
}

/// Figures stacked vertically in one image; `.svg` or `.png` by `path`'s extension.
pub fn write(path: &Path, figures: &[Figure]) -> Result<(), PlotError> {
    let name = path.display().to_string();
    let ext = check_format(path)?;
    let size = image_size(figures)?;
    register_font();
    let draw = |e: String| PlotError::Draw {
        path: name.clone(),
        message: e,
    };
    match ext.as_str() {
        "svg" => {
            let root = SVGBackend::new(path, size).into_drawing_area();
            draw_figures(&root, figures).map_err(|e| draw(e.to_string()))?;
            root.present().map_err(|e| draw(e.to_string()))
        }
        "png" => {
            let root = BitMapBackend::new(path, size).into_drawing_area();
            draw_figures(&root, figures).map_err(|e| draw(e.to_string()))?;
            root.present().map_err(|e| draw(e.to_string()))
        }
        _ => Err(PlotError::Format { path: name }),
    }
}

/// One figure as an SVG document (for embedding in the HTML report).
pub fn svg_string(figure: &Figure) -> Result<String, PlotError> {
    let figures = std::slice::from_ref(figure);
    let size = image_size(figures)?;
    register_font();
    let mut out = String::new();
    {
        let root = SVGBackend::with_string(&mut out, size).into_drawing_area();
        draw_figures(&root, figures).map_err(|e| PlotError::Draw {
            path: "report".into(),
            message: e.to_string(),
        })?;
        root.present().map_err(|e| PlotError::Draw {
            path: "report".into(),
            message: e.to_string(),
        })?;
    }
    Ok(out)
}

fn image_size(figures: &[Figure]) -> Result<(u32, u32), PlotError> {
    let columns = figures.iter().map(|f| f.panels.len()).max().unwrap_or(0) as u32;
    if columns == 0 {
        return Err(PlotError::Empty);
    }
    Ok((
        columns * PANEL_W,
        figures.len() as u32 * (PANEL_H + TITLE_H),
    ))
}

/// The drawing backend's error (the file could not be written, a glyph not drawn).
type DrawError<DB> = DrawingAreaErrorKind<<DB as DrawingBackend>::ErrorType>;

fn draw_figures<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    figures: &[Figure],
) -> Result<(), DrawError<DB>> {
    root.fill(&WHITE)?;
    let columns = figures.iter().map(|f| f.panels.len()).max().unwrap_or(1);
    for (row, figure) in root.split_evenly((figures.len(), 1)).iter().zip(figures) {
        let body = row.titled(&figure.title, ("sans-serif", 24))?;
        for (area, panel) in body.split_evenly((1, columns)).iter().zip(&figure.panels) {
            draw_panel(area, panel)?;
        }
    }
    Ok(())
}

/// Axis limits covering every positive finite point, padded to whole decades where close.
fn limits(points: impl Iterator<Item = f64>) -> Option<(f64, f64)> {
    let (lo, hi) = points
        .filter(|v| v.is_finite() && *v > 0.0)
        .fold((f64::INFINITY, 0.0f64), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
    (hi > 0.0).then(|| {
        // Log axes are labelled at powers of ten: a range of less than two decades is widened
        // to the powers of ten around it, so that every axis carries labels at both ends.
        let pad = (hi / lo).powf(0.04).max(1.05);
        let (lo, hi) = (lo / pad, hi * pad);
        if hi / lo >= 100.0 {
            return (lo, hi);
        }
        let (a, b) = (lo.log10().floor(), hi.log10().ceil());
        (10f64.powf(a), 10f64.powf(b.max(a + 1.0)))
    })
}

fn draw_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    panel: &Panel,
) -> Result<(), DrawError<DB>> {
    let xs = panel.lines.iter().flat_map(|l| l.x.iter().copied());
    let ys = panel.lines.iter().flat_map(|l| {
        l.y.iter()
            .chain(l.band.iter().flat_map(|(lo, hi)| lo.iter().chain(hi)))
            .copied()
    });
    let (Some((x0, x1)), Some((y0, y1))) = (limits(xs), limits(ys)) else {
        return Ok(()); // nothing positive to draw on log axes
    };
    let mut chart = ChartBuilder::on(area)
        .caption(&panel.title, ("sans-serif", 18))
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(70)
        .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())?;
    chart
        .configure_mesh()
        .x_desc(&panel.x_label)
        .y_desc(&panel.y_label)
        .x_label_formatter(&|v| format!("{v:.0e}"))
        .y_labels(8)
        .y_label_formatter(&|v| format!("{v:.1e}"))
        .label_style(("sans-serif", 13))
        .light_line_style(RGBColor(235, 235, 235))
        .draw()?;
    for line in &panel.lines {
        let color = PALETTE[line.color % PALETTE.len()];
        if let Some((lo, hi)) = &line.band {
            let outline: Vec<(f64, f64)> = line
                .x
                .iter()
                .zip(hi)
                .chain(line.x.iter().zip(lo).rev())
                .filter(|(x, y)| **x > 0.0 && **y > 0.0 && y.is_finite())
                .map(|(x, y)| (*x, *y))
                .collect();
            chart.draw_series(std::iter::once(Polygon::new(outline, color.mix(0.18))))?;
        }
        let points: Vec<(f64, f64)> = line
            .x
            .iter()
            .zip(&line.y)
            .filter(|(x, y)| **x > 0.0 && **y > 0.0 && y.is_finite())
            .map(|(x, y)| (*x, *y))
            .collect();
        let style = color.stroke_width(if line.dashed { 1 } else { 2 });
        let series = if line.dashed {
            chart.draw_series(DashedLineSeries::new(points, 6, 4, style))
        } else {
            chart.draw_series(LineSeries::new(points, style))
        }?;
        if !line.label.is_empty() {
            series.label(&line.label).legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 18, y)], color.stroke_width(2))
            });
        }
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(RGBColor(180, 180, 180))
        .label_font(("sans-serif", 12))
        .position(SeriesLabelPosition::UpperRight)
        .draw()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn figure() -> Figure {
        let x: Vec<f64> = (0..20).map(|i| 10f64.powf(i as f64 / 5.0)).collect();
        let y: Vec<f64> = x.iter().map(|t| 1e-3 / t.sqrt()).collect();
        Figure {
            title: "Gyroscope".into(),
            panels: vec![Panel {
                title: "Allan deviation".into(),
                x_label: "tau (s)".into(),
                y_label: "rad/s".into(),
                lines: vec![Line {
                    label: "gx".into(),
                    band: Some((
                        y.iter().map(|v| v * 0.9).collect(),
                        y.iter().map(|v| v * 1.1).collect(),
                    )),
                    x,
                    y,
                    color: 0,
                    dashed: false,
                }],
            }],
        }
    }

    #[test]
    fn svg_has_the_text_and_a_curve() {
        let svg = svg_string(&figure()).unwrap();
        assert!(svg.starts_with("<svg"), "{}", &svg[..40]);
        assert!(svg.contains("Gyroscope") && svg.contains("Allan deviation"));
        assert!(svg.contains("<polyline") || svg.contains("<path"));
    }

    #[test]
    fn png_and_bad_extension() {
        let scratch = tempfile::tempdir().unwrap();
        let dir = scratch.path();
        let png = dir.join("a.png");
        write(&png, &[figure()]).unwrap();
        let bytes = std::fs::read(&png).unwrap();
        assert_eq!(&bytes[1..4], b"PNG");
        let err = write(&dir.join("a.pdf"), &[figure()]).unwrap_err();
        assert!(
            err.to_string()
                .contains("a.pdf: plots are written as .svg or .png")
        );
        assert!(matches!(write(&png, &[]), Err(PlotError::Empty)));
    }
}
