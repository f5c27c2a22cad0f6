//! A small SVG writer for the report's pictures: shapes in world units
//! mapped onto a picture of fixed width, with every text escaped.

use std::fmt::Write;

/// Escape text for HTML and SVG (element content and attribute values).
pub fn escape(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            _ => out.push(c),
        }
    }
    out
}

/// A picture of the rectangle `[u0, u1] x [v0, v1]` of some plane (v up),
/// drawn `width` pixels wide with `margin` pixels around.
pub struct Svg {
    u0: f64,
    v1: f64,
    scale: f64,
    margin: f64,
    width: f64,
    height: f64,
    body: String,
    /// Picture rectangles `[x0, y0, x1, y1]` already taken by markers and
    /// labels, which a new label must not overlap.
    taken: Vec<[f64; 4]>,
}

/// Approximate extent of 11 px text: width per character and height.
const CHAR_W: f64 = 6.4;
const TEXT_H: f64 = 11.0;

fn overlaps(a: &[f64; 4], b: &[f64; 4]) -> bool {
    a[0] < b[2] && b[0] < a[2] && a[1] < b[3] && b[1] < a[3]
}

impl Svg {
    pub fn new(bounds: [[f64; 2]; 2], width: f64, margin: f64) -> Self {
        let [[u0, v0], [u1, v1]] = bounds;
        let span_u = (u1 - u0).max(1e-9);
        let scale = (width - 2.0 * margin) / span_u;
        let height = (v1 - v0).max(0.0) * scale + 2.0 * margin;
        Self {
            u0,
            v1,
            scale,
            margin,
            width,
            height,
            body: String::new(),
            taken: Vec::new(),
        }
    }

    /// Picture coordinates of a plane point.
    pub fn at(&self, u: f64, v: f64) -> (f64, f64) {
        (
            self.margin + (u - self.u0) * self.scale,
            self.margin + (self.v1 - v) * self.scale,
        )
    }

    /// Pixels per plane unit.
    pub fn scale(&self) -> f64 {
        self.scale
    }

    /// An axis-aligned square of side `size` centred on `(u, v)`.
    pub fn square(&mut self, u: f64, v: f64, size: f64, fill: &str) {
        let (x, y) = self.at(u - size / 2.0, v + size / 2.0);
        let s = size * self.scale;
        let _ = write!(
            self.body,
            r#"<rect x="{x:.1}" y="{y:.1}" width="{s:.2}" height="{s:.2}" fill="{fill}"/>"#
        );
    }

    pub fn polyline(&mut self, points: &[(f64, f64)], stroke: &str, width: f64) {
        let mut d = String::new();
        for (u, v) in points {
            let (x, y) = self.at(*u, *v);
            let _ = write!(d, "{x:.1},{y:.1} ");
        }
        let _ = write!(
            self.body,
            r#"<polyline points="{}" fill="none" stroke="{stroke}" stroke-width="{width}" stroke-linejoin="round"/>"#,
            d.trim_end()
        );
    }

    pub fn circle(&mut self, u: f64, v: f64, radius_px: f64, fill: &str, stroke: &str) {
        let (x, y) = self.at(u, v);
        let _ = write!(
            self.body,
            r#"<circle cx="{x:.1}" cy="{y:.1}" r="{radius_px}" fill="{fill}" stroke="{stroke}" stroke-width="1"/>"#
        );
    }

    /// Text at a plane point, nudged by `(dx, dy)` pixels.
    pub fn label(&mut self, u: f64, v: f64, dx: f64, dy: f64, text: &str) {
        let (x, y) = self.at(u, v);
        let _ = write!(
            self.body,
            r#"<text x="{:.1}" y="{:.1}" font-size="11">{}</text>"#,
            x + dx,
            y + dy,
            escape(text)
        );
    }

    /// Mark a circle of `radius_px` around a plane point as taken.
    pub fn take(&mut self, u: f64, v: f64, radius_px: f64) {
        let (x, y) = self.at(u, v);
        self.taken
            .push([x - radius_px, y - radius_px, x + radius_px, y + radius_px]);
    }

    /// Text beside a plane point, `gap` pixels from it, at the first of
    /// eight positions (right, left, above, below, then the corners, then
    /// twice as far with a leader line) where it overlaps no other label or
    /// marker and stays in the picture. Returns whether it found one.
    pub fn label_clear(&mut self, u: f64, v: f64, gap: f64, text: &str, size: f64) -> bool {
        let (x, y) = self.at(u, v);
        let w = CHAR_W * size / TEXT_H * text.chars().count() as f64;
        let h = size;
        for far in [1.0, 2.2, 3.4] {
            let g = gap * far;
            // Top-left corners of the text box around the point.
            let spots = [
                (x + g, y - h / 2.0),
                (x - g - w, y - h / 2.0),
                (x - w / 2.0, y - g - h),
                (x - w / 2.0, y + g),
                (x + g * 0.7, y - g * 0.7 - h),
                (x - g * 0.7 - w, y - g * 0.7 - h),
                (x + g * 0.7, y + g * 0.7),
                (x - g * 0.7 - w, y + g * 0.7),
            ];
            for (tx, ty) in spots {
                let rect = [tx - 1.0, ty - 1.0, tx + w + 1.0, ty + h + 1.0];
                let inside = rect[0] >= 0.0
                    && rect[1] >= 0.0
                    && rect[2] <= self.width
                    && rect[3] <= self.height;
                if !inside || self.taken.iter().any(|t| overlaps(t, &rect)) {
                    continue;
                }
                self.taken.push(rect);
                if far > 1.0 {
                    let (lx, ly) = (x.clamp(tx, tx + w), y.clamp(ty, ty + h));
                    let _ = write!(
                        self.body,
                        r##"<line x1="{x:.1}" y1="{y:.1}" x2="{lx:.1}" y2="{ly:.1}" stroke="#6b7280" stroke-width="0.8"/>"##
                    );
                }
                let _ = write!(
                    self.body,
                    r#"<text x="{tx:.1}" y="{:.1}" font-size="{size}">{}</text>"#,
                    ty + h * 0.85,
                    escape(text)
                );
                return true;
            }
        }
        false
    }

    /// A vertical colour ramp from `low` to `high` (hex colours by height)
    /// in the upper right corner, labelled with its ends.
    pub fn ramp(&mut self, colours: &[&str], low: &str, high: &str) {
        let (x, h) = (self.width - 16.0, 80.0);
        let step = h / colours.len().max(1) as f64;
        for (i, c) in colours.iter().enumerate() {
            let y = 6.0 + h - step * (i as f64 + 1.0);
            let _ = write!(
                self.body,
                r#"<rect x="{x}" y="{y:.1}" width="10" height="{:.1}" fill="{c}"/>"#,
                step + 0.3
            );
        }
        let _ = write!(
            self.body,
            r#"<text x="{tx}" y="14" font-size="10" text-anchor="end">{}</text><text x="{tx}" y="{by}" font-size="10" text-anchor="end">{}</text>"#,
            escape(high),
            escape(low),
            tx = x - 3.0,
            by = 6.0 + h,
        );
        self.taken.push([x - 60.0, 0.0, self.width, 6.0 + h + 4.0]);
    }

    /// A scale bar of `metres` in the lower left corner.
    pub fn scale_bar(&mut self, metres: f64) {
        let len = metres * self.scale;
        let y = self.height - 6.0;
        let x = 6.0;
        self.taken
            .push([0.0, y - 12.0, x + len + 40.0, self.height]);
        let _ = write!(
            self.body,
            r##"<path d="M{x} {y0}V{y}H{x1}V{y0}" fill="none" stroke="#333"/><text x="{tx}" y="{ty}" font-size="10">{metres} m</text>"##,
            y0 = y - 4.0,
            x1 = x + len,
            tx = x + len + 4.0,
            ty = y,
        );
    }

    /// The finished picture, with `title` as its accessible name.
    pub fn finish(self, title: &str) -> String {
        format!(
            r#"<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 {w:.0} {h:.0}" width="{w:.0}" height="{h:.0}" role="img"><title>{t}</title>{b}</svg>"#,
            w = self.width,
            h = self.height,
            t = escape(title),
            b = self.body
        )
    }
}

/// A horizontal bar chart of `(label, value)`, values shown at the bar ends.
pub fn bar_chart(bars: &[(String, f64)], colour: &str, title: &str) -> String {
    let (label_w, bar_w, row) = (190.0, 300.0, 22.0);
    let max = bars.iter().map(|b| b.1).fold(0.0_f64, f64::max).max(1e-9);
    let height = row * bars.len() as f64 + 8.0;
    let mut body = String::new();
    for (i, (label, value)) in bars.iter().enumerate() {
        let y = 4.0 + row * i as f64;
        let w = (value / max * bar_w).max(1.0);
        let _ = write!(
            body,
            r#"<text x="{lx}" y="{ty:.1}" font-size="12" text-anchor="end">{l}</text><rect x="{bx}" y="{y:.1}" width="{w:.1}" height="{h}" fill="{colour}"/><text x="{vx:.1}" y="{ty:.1}" font-size="12">{v}</text>"#,
            lx = label_w - 6.0,
            ty = y + row * 0.65,
            l = escape(label),
            bx = label_w,
            h = row - 6.0,
            vx = label_w + w + 4.0,
            v = value
        );
    }
    format!(
        r#"<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 {w} {height}" width="{w}" height="{height}" role="img"><title>{t}</title>{body}</svg>"#,
        w = label_w + bar_w + 60.0,
        t = escape(title)
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn escapes_markup_and_quotes() {
        assert_eq!(
            escape(r#"<script>"a" & 'b'</script>"#),
            "&lt;script&gt;&quot;a&quot; &amp; &#39;b&#39;&lt;/script&gt;"
        );
    }

    #[test]
    fn labels_of_one_spot_never_overlap() {
        let mut svg = Svg::new([[0.0, 0.0], [10.0, 10.0]], 300.0, 10.0);
        for text in ["1", "12", "3", "4", "5"] {
            svg.take(5.0, 5.0, 6.0);
            assert!(svg.label_clear(5.0, 5.0, 8.0, text, 11.0));
        }
        let boxes = &svg.taken;
        for (i, a) in boxes.iter().enumerate() {
            for b in &boxes[i + 1..] {
                // Markers at one spot overlap each other; labels overlap nothing.
                let marker = |r: &[f64; 4]| (r[2] - r[0] - 12.0).abs() < 1e-9;
                if !(marker(a) && marker(b)) {
                    assert!(!overlaps(a, b), "{a:?} {b:?}");
                }
            }
        }
    }

    #[test]
    fn maps_the_plane_with_v_up() {
        let svg = Svg::new([[0.0, 0.0], [10.0, 5.0]], 120.0, 10.0);
        assert_eq!(svg.scale(), 10.0);
        assert_eq!(svg.at(0.0, 5.0), (10.0, 10.0));
        assert_eq!(svg.at(10.0, 0.0), (110.0, 60.0));
        let text = svg.finish("t<");
        assert!(text.contains(r#"viewBox="0 0 120 70""#));
        assert!(text.contains("<title>t&lt;</title>"));
    }
}
