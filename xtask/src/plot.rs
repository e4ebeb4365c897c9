//! Minimal SVG plots for the validation and benchmark reports: labelled scatter and line series
//! on linear or logarithmic axes, written as plain SVG text (no plotting dependency).

use std::fmt::Write as _;

/// One series of points.
pub(crate) struct Series {
    pub(crate) name: String,
    pub(crate) colour: &'static str,
    pub(crate) points: Vec<(f64, f64)>,
    /// Joined by a line (else markers only).
    pub(crate) line: bool,
    /// A label beside each point (empty: none).
    pub(crate) labels: Vec<String>,
}

/// A plot.
pub(crate) struct Plot {
    pub(crate) title: String,
    pub(crate) x_label: String,
    pub(crate) y_label: String,
    pub(crate) log_x: bool,
    pub(crate) log_y: bool,
    pub(crate) series: Vec<Series>,
}

fn escape(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

/// Tick positions (in axis units: log10 for log axes) covering [lo, hi].
fn ticks(lo: f64, hi: f64, log: bool) -> Vec<f64> {
    if log {
        (lo.floor() as i32..=hi.ceil() as i32)
            .map(f64::from)
            .collect()
    } else {
        (0..=4)
            .map(|k| lo + (hi - lo) * f64::from(k) / 4.0)
            .collect()
    }
}

fn tick_label(value: f64, log: bool) -> String {
    if log {
        format!("1e{}", value as i32)
    } else if value.abs() >= 100.0 || value == 0.0 {
        format!("{value:.0}")
    } else {
        format!("{value:.2}")
    }
}

impl Plot {
    /// The plot as an SVG document. Points that a log axis cannot show (≤ 0) are left out.
    pub(crate) fn svg(&self) -> String {
        let (width, height, margin) = (680.0, 440.0, 72.0);
        let map = |v: f64, log: bool| if log { v.log10() } else { v };
        let visible = |&(x, y): &(f64, f64)| {
            x.is_finite() && y.is_finite() && (!self.log_x || x > 0.0) && (!self.log_y || y > 0.0)
        };
        let all: Vec<(f64, f64)> = self
            .series
            .iter()
            .flat_map(|s| s.points.iter().copied().filter(visible))
            .map(|(x, y)| (map(x, self.log_x), map(y, self.log_y)))
            .collect();
        let bounds = |values: Vec<f64>, log: bool| {
            let lo = values.iter().copied().fold(f64::INFINITY, f64::min);
            let hi = values.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            if !lo.is_finite() {
                return (0.0, 1.0);
            }
            if log {
                (lo.floor(), hi.ceil().max(lo.floor() + 1.0))
            } else {
                let pad = 0.05 * (hi - lo).max(1e-12);
                ((lo - pad).min(0.0f64.max(lo - pad)), hi + pad)
            }
        };
        let (x0, x1) = bounds(all.iter().map(|p| p.0).collect(), self.log_x);
        let (y0, y1) = bounds(all.iter().map(|p| p.1).collect(), self.log_y);
        let px = |x: f64| margin + (x - x0) / (x1 - x0) * (width - 2.0 * margin);
        let py = |y: f64| height - margin - (y - y0) / (y1 - y0) * (height - 2.0 * margin);
        let mut svg = String::new();
        let mut w = |line: String| {
            svg.push_str(&line);
            svg.push('\n');
        };
        w(format!(
            "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{width}\" height=\"{height}\" font-family=\"sans-serif\" font-size=\"12\">"
        ));
        w("<rect width=\"100%\" height=\"100%\" fill=\"white\"/>".into());
        w(format!(
            "<text x=\"{}\" y=\"26\" text-anchor=\"middle\" font-size=\"15\">{}</text>",
            width / 2.0,
            escape(&self.title)
        ));
        let (left, right, bottom, top) = (margin, width - margin, height - margin, margin);
        w(format!(
            "<rect x=\"{left}\" y=\"{top}\" width=\"{}\" height=\"{}\" fill=\"none\" stroke=\"black\"/>",
            right - left,
            bottom - top
        ));
        for t in ticks(x0, x1, self.log_x) {
            w(format!(
                "<line x1=\"{0:.1}\" y1=\"{top}\" x2=\"{0:.1}\" y2=\"{bottom}\" stroke=\"#ddd\"/>",
                px(t)
            ));
            w(format!(
                "<text x=\"{:.1}\" y=\"{}\" text-anchor=\"middle\">{}</text>",
                px(t),
                bottom + 18.0,
                tick_label(t, self.log_x)
            ));
        }
        for t in ticks(y0, y1, self.log_y) {
            w(format!(
                "<line x1=\"{left}\" y1=\"{0:.1}\" x2=\"{right}\" y2=\"{0:.1}\" stroke=\"#ddd\"/>",
                py(t)
            ));
            w(format!(
                "<text x=\"{}\" y=\"{:.1}\" text-anchor=\"end\">{}</text>",
                left - 6.0,
                py(t) + 4.0,
                tick_label(t, self.log_y)
            ));
        }
        w(format!(
            "<text x=\"{}\" y=\"{}\" text-anchor=\"middle\">{}</text>",
            width / 2.0,
            height - 28.0,
            escape(&self.x_label)
        ));
        w(format!(
            "<text x=\"20\" y=\"{0}\" text-anchor=\"middle\" transform=\"rotate(-90 20 {0})\">{1}</text>",
            height / 2.0,
            escape(&self.y_label)
        ));
        for (k, series) in self.series.iter().enumerate() {
            let points: Vec<(usize, f64, f64)> = series
                .points
                .iter()
                .enumerate()
                .filter(|(_, p)| visible(p))
                .map(|(i, &(x, y))| (i, px(map(x, self.log_x)), py(map(y, self.log_y))))
                .collect();
            if series.line && points.len() > 1 {
                let path: Vec<String> = points
                    .iter()
                    .map(|(_, x, y)| format!("{x:.1},{y:.1}"))
                    .collect();
                w(format!(
                    "<polyline points=\"{}\" fill=\"none\" stroke=\"{}\" stroke-width=\"1.5\"/>",
                    path.join(" "),
                    series.colour
                ));
            }
            for (i, x, y) in &points {
                w(format!(
                    "<circle cx=\"{x:.1}\" cy=\"{y:.1}\" r=\"3.5\" fill=\"{}\"/>",
                    series.colour
                ));
                if let Some(label) = series.labels.get(*i) {
                    w(format!(
                        "<text x=\"{:.1}\" y=\"{:.1}\" font-size=\"10\">{}</text>",
                        x + 6.0,
                        y - 5.0,
                        escape(label)
                    ));
                }
            }
            let legend_y = top + 16.0 + 16.0 * k as f64;
            w(format!(
                "<circle cx=\"{}\" cy=\"{legend_y}\" r=\"4\" fill=\"{}\"/><text x=\"{}\" y=\"{}\">{}</text>",
                right - 190.0,
                series.colour,
                right - 180.0,
                legend_y + 4.0,
                escape(&series.name)
            ));
        }
        let mut out = svg;
        writeln!(out, "</svg>").expect("writing to a String");
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plots_are_well_formed_and_skip_unplottable_points() {
        let plot = Plot {
            title: "a < b & c".into(),
            x_label: "x".into(),
            y_label: "y".into(),
            log_x: true,
            log_y: true,
            series: vec![Series {
                name: "s".into(),
                colour: "#000",
                points: vec![(1.0, 1.0), (10.0, 0.1), (100.0, 0.0), (f64::NAN, 1.0)],
                line: true,
                labels: vec!["one".into(), "two".into()],
            }],
        };
        let svg = plot.svg();
        assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"));
        assert!(svg.contains("a &lt; b &amp; c"));
        // Two plottable points plus the legend marker.
        assert_eq!(svg.matches("<circle").count(), 3);
        assert!(svg.contains(">one<") && svg.contains(">two<"));
    }
}
