//! Line charts of the benchmark suites, drawn with plotters into both SVG and PNG. Text uses the
//! embedded DejaVu Sans (assets/fonts), so no system font library is involved.

use envis::error::{Error, Result};
use plotters::coord::Shift;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;
use std::path::Path;

/// One line of a chart: its points (in data units), colour (`#rrggbb`), and whether it is dashed
/// (dashed lines have no point markers).
pub struct Series {
    pub name: String,
    pub color: &'static str,
    pub points: Vec<(f64, f64)>,
    pub dashed: bool,
}

/// A line chart, log or linear on each axis.
pub struct Chart {
    pub title: String,
    pub xlabel: &'static str,
    pub ylabel: &'static str,
    pub xlog: bool,
    pub ylog: bool,
    pub series: Vec<Series>,
}

const SIZE: (u32, u32) = (800, 520);
const FONT: &[u8] = include_bytes!("../../../../assets/fonts/DejaVuSans.ttf");

fn register_font() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        // The font is compiled in and known to parse; a failure here is a build defect.
        if plotters::style::register_font("sans-serif", FontStyle::Normal, FONT).is_err() {
            panic!("the embedded DejaVu Sans font did not load");
        }
    });
}

/// The plotting area: plain f64 coordinates (log axes are plotted as log10 of the data).
type Plot<'a, DB> = ChartContext<'a, DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

/// Tick label on a log axis (plot coordinate = log10): `1eN` at whole decades, none between.
fn decade(v: &f64) -> String {
    if (v - v.round()).abs() < 1e-6 {
        format!("1e{}", v.round() as i64)
    } else {
        String::new()
    }
}

/// Tick label on a linear axis: up to 3 decimals, trailing zeros dropped.
fn plain(v: &f64) -> String {
    format!("{v:.3}")
        .trim_end_matches('0')
        .trim_end_matches('.')
        .to_string()
}

/// The tick label format for a log or linear axis.
fn tick_format(log: bool) -> fn(&f64) -> String {
    if log { decade } else { plain }
}

fn rgb(hex: &str) -> RGBColor {
    let v = u32::from_str_radix(hex.trim_start_matches('#'), 16).unwrap_or(0);
    RGBColor((v >> 16) as u8, (v >> 8) as u8, v as u8)
}

impl Chart {
    /// Axis range in plot coordinates (log10 of the data on a log axis), whole decades on log axes.
    fn range(&self, pick: impl Fn(&(f64, f64)) -> f64, log: bool) -> (f64, f64) {
        let v: Vec<f64> = self
            .series
            .iter()
            .flat_map(|s| s.points.iter())
            .map(pick)
            .filter(|v| v.is_finite() && (!log || *v > 0.0))
            .map(|v| if log { v.log10() } else { v })
            .collect();
        let (lo, hi) = (
            v.iter().copied().fold(f64::INFINITY, f64::min),
            v.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        );
        if v.is_empty() {
            (0.0, 1.0)
        } else if log {
            (lo.floor(), hi.ceil().max(lo.floor() + 1.0))
        } else {
            (lo.min(0.0), if hi > lo.min(0.0) { hi * 1.05 } else { 1.0 })
        }
    }

    /// The whole chart on `root`: axes, every series, the legend.
    fn draw<DB: DrawingBackend>(
        &self,
        root: DrawingArea<DB, Shift>,
    ) -> std::result::Result<(), String> {
        let e = |x: DrawingAreaErrorKind<DB::ErrorType>| x.to_string();
        root.fill(&WHITE).map_err(e)?;
        let (x0, x1) = self.range(|p| p.0, self.xlog);
        let (y0, y1) = self.range(|p| p.1, self.ylog);
        let mut cc = ChartBuilder::on(&root)
            .caption(self.title.as_str(), ("sans-serif", 18))
            .margin(12)
            .x_label_area_size(42)
            .y_label_area_size(64)
            .build_cartesian_2d(x0..x1, y0..y1)
            .map_err(e)?;
        self.draw_mesh(&mut cc, (x0, x1), (y0, y1)).map_err(e)?;
        for s in &self.series {
            self.draw_line(&mut cc, s).map_err(e)?;
        }
        cc.configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .background_style(WHITE.mix(0.85))
            .border_style(RGBColor(180, 180, 180))
            .label_font(("sans-serif", 13))
            .draw()
            .map_err(e)?;
        root.present().map_err(e)
    }

    /// The grid, axis labels and ticks over the plot ranges `(x0, x1)` and `(y0, y1)`: one tick
    /// per decade on a log axis, 8 on a linear one.
    fn draw_mesh<DB: DrawingBackend>(
        &self,
        cc: &mut Plot<'_, DB>,
        (x0, x1): (f64, f64),
        (y0, y1): (f64, f64),
    ) -> std::result::Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
        let (xf, yf) = (tick_format(self.xlog), tick_format(self.ylog));
        cc.configure_mesh()
            .x_desc(self.xlabel)
            .y_desc(self.ylabel)
            .x_labels(if self.xlog { (x1 - x0) as usize + 1 } else { 8 })
            .y_labels(if self.ylog { (y1 - y0) as usize + 1 } else { 8 })
            .x_label_formatter(&xf)
            .y_label_formatter(&yf)
            .light_line_style(WHITE)
            .bold_line_style(RGBColor(221, 221, 221))
            .label_style(("sans-serif", 13))
            .draw()
    }

    /// One series: its finite points as a line (dashed, or solid with point markers) and its
    /// legend entry.
    fn draw_line<DB: DrawingBackend>(
        &self,
        cc: &mut Plot<'_, DB>,
        s: &Series,
    ) -> std::result::Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
        let to = |log: bool, v: f64| if log { v.max(1e-300).log10() } else { v };
        let color = rgb(s.color);
        let pts: Vec<(f64, f64)> = s
            .points
            .iter()
            .filter(|p| p.0.is_finite() && p.1.is_finite())
            .map(|p| (to(self.xlog, p.0), to(self.ylog, p.1)))
            .collect();
        let style = ShapeStyle {
            color: color.to_rgba(),
            filled: false,
            stroke_width: if s.dashed { 1 } else { 2 },
        };
        let legend = move |(x, y): (i32, i32)| PathElement::new(vec![(x, y), (x + 20, y)], style);
        if s.dashed {
            cc.draw_series(DashedLineSeries::new(pts, 5, 4, style))?
                .label(s.name.as_str())
                .legend(legend);
        } else {
            cc.draw_series(LineSeries::new(pts.iter().copied(), style))?
                .label(s.name.as_str())
                .legend(legend);
            cc.draw_series(pts.iter().map(|p| Circle::new(*p, 3, color.filled())))?;
        }
        Ok(())
    }

    /// The chart as a standalone SVG document.
    pub fn svg(&self) -> Result<String> {
        register_font();
        let mut s = String::new();
        self.draw(SVGBackend::with_string(&mut s, SIZE).into_drawing_area())
            .map_err(|e| Error::invalid(format!("chart '{}': {e}", self.title)))?;
        s.push('\n');
        Ok(s)
    }

    /// The chart as 8-bit RGB pixels, `SIZE` row-major.
    pub fn rgb8(&self) -> Result<Vec<u8>> {
        register_font();
        let mut buf = vec![0u8; (SIZE.0 * SIZE.1 * 3) as usize];
        self.draw(BitMapBackend::with_buffer(&mut buf, SIZE).into_drawing_area())
            .map_err(|e| Error::invalid(format!("chart '{}': {e}", self.title)))?;
        Ok(buf)
    }

    /// Write `<stem>.svg` and `<stem>.png` into `dir`; returns the two file names.
    pub fn write(&self, dir: &Path, stem: &str) -> Result<(String, String)> {
        let (svg, png) = (format!("{stem}.svg"), format!("{stem}.png"));
        let p = dir.join(&svg);
        std::fs::write(&p, self.svg()?)
            .map_err(|e| Error::file(&p, format!("cannot write: {e}")))?;
        envis::render::output::write_png_rgb8(
            &dir.join(&png),
            SIZE.0 as usize,
            SIZE.1 as usize,
            &self.rgb8()?,
        )?;
        Ok((svg, png))
    }
}
