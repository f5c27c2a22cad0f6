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

    /// A scale bar of `metres` in the lower left corner.
    pub fn scale_bar(&mut self, metres: f64) {
        let len = metres * self.scale;
        let y = self.height - 6.0;
        let x = 6.0;
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
