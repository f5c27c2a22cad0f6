//! What a defect is: a crack, or one of the area defects an element record
//! counts (spalls, exposed reinforcement, efflorescence, rust staining,
//! corrosion), and the kind a model's class name means.

crate::kind! {
    /// What a defect is, as detections, candidates and the record name it.
    pub enum DefectKind("defect kind") {
        /// A crack: a line, measured by its width (AASHTO 1130, 1110, 1010).
        Crack = "crack",
        /// Concrete broken out of the surface: spalls, delaminations and
        /// patched areas (AASHTO 1080).
        Spall = "spall",
        /// Reinforcing bars showing (AASHTO 1090).
        ExposedRebar = "exposed_rebar",
        /// White deposits leached out of concrete (AASHTO 1120).
        Efflorescence = "efflorescence",
        /// Rust staining on concrete (AASHTO 1120).
        RustStain = "rust_stain",
        /// Corrosion of steel (AASHTO 1000).
        Corrosion = "corrosion",
    }
}

/// Class names data sets and segmenters use for each kind, beside the
/// kind's own name, lower case with `_` between words.
const SYNONYMS: &[(&str, DefectKind)] = &[
    ("cracks", DefectKind::Crack),
    ("cracking", DefectKind::Crack),
    ("spalling", DefectKind::Spall),
    ("spalls", DefectKind::Spall),
    ("exposed_reinforcement", DefectKind::ExposedRebar),
    ("exposed_bars", DefectKind::ExposedRebar),
    ("exposedrebars", DefectKind::ExposedRebar),
    ("rebar", DefectKind::ExposedRebar),
    ("rust_staining", DefectKind::RustStain),
    ("rust", DefectKind::RustStain),
    ("rust_stains", DefectKind::RustStain),
]; // dacl10k names its classes Spalling, ExposedRebars, Efflorescence, Rust

impl DefectKind {
    /// An area defect: measured by its area, not a width.
    pub fn is_area(self) -> bool {
        self != Self::Crack
    }

    /// The kind a model's class `name` means (`Spalling`, `exposed rebar`,
    /// `rust-staining`), if any: case, spaces and dashes aside, the kind's
    /// own name or a synonym data sets use.
    pub fn of_class(name: &str) -> Option<Self> {
        let name: String = name
            .trim()
            .to_lowercase()
            .chars()
            .map(|c| if c == ' ' || c == '-' { '_' } else { c })
            .collect();
        Self::ALL
            .iter()
            .copied()
            .find(|k| k.as_str() == name)
            .or_else(|| SYNONYMS.iter().find(|(s, _)| *s == name).map(|(_, k)| *k))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn class_names_as_data_sets_spell_them_mean_their_kinds() {
        for (name, kind) in [
            ("crack", Some(DefectKind::Crack)),
            ("Spalling", Some(DefectKind::Spall)),
            ("exposed_rebar", Some(DefectKind::ExposedRebar)),
            ("Exposed Rebar", Some(DefectKind::ExposedRebar)),
            ("ExposedRebars", Some(DefectKind::ExposedRebar)),
            ("rust-staining", Some(DefectKind::RustStain)),
            ("Efflorescence", Some(DefectKind::Efflorescence)),
            ("background", None),
            ("graffiti", None),
        ] {
            assert_eq!(DefectKind::of_class(name), kind, "{name}");
        }
        assert!(!DefectKind::Crack.is_area() && DefectKind::Spall.is_area());
    }
}
