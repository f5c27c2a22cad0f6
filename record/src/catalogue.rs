//! The manual's elements and cracking defects postflight records, each
//! declared once: its number, its name, its unit and the cracking defect
//! it carries (see docs/cli.md `postflight record` for the edition).

use postflight_core::condition::Material;
use postflight_core::outputs::record::Unit;

/// An AASHTO element.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct AashtoElement {
    pub number: u16,
    /// The manual's name.
    pub name: &'static str,
    pub unit: Unit,
    /// How its cracks are recorded.
    pub cracking: Cracking,
}

/// Which cracking defect an element's cracks are, by its material.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Cracking {
    /// 1130 (reinforced concrete) or 1110 (prestressed): states by width
    /// and, in a pattern, by spacing.
    Concrete(Material),
    /// 1010: a crack in steel is state 3 until a reviewer says it is
    /// arrested (state 2) or needs a structural review (state 4).
    Steel,
}

/// A defect of the manual.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct AashtoDefect {
    pub number: u16,
    pub name: &'static str,
}

impl Cracking {
    /// The defect its cracks are recorded as.
    pub fn defect(self) -> AashtoDefect {
        match self {
            Self::Concrete(Material::ReinforcedConcrete) => AashtoDefect {
                number: 1130,
                name: "Cracking (RC and Other)",
            },
            Self::Concrete(Material::PrestressedConcrete) => AashtoDefect {
                number: 1110,
                name: "Cracking (PSC)",
            },
            Self::Steel => AashtoDefect {
                number: 1010,
                name: "Cracking",
            },
        }
    }
}

const RC: Cracking = Cracking::Concrete(Material::ReinforcedConcrete);
const PSC: Cracking = Cracking::Concrete(Material::PrestressedConcrete);

/// Every element postflight can record, by number.
pub const ELEMENTS: &[AashtoElement] = &[
    element(12, "Reinforced Concrete Deck", Unit::SquareMetres, RC),
    element(13, "Prestressed Concrete Deck", Unit::SquareMetres, PSC),
    element(38, "Reinforced Concrete Slab", Unit::SquareMetres, RC),
    element(107, "Steel Open Girder/Beam", Unit::Metres, Cracking::Steel),
    element(
        109,
        "Prestressed Concrete Open Girder/Beam",
        Unit::Metres,
        PSC,
    ),
    element(
        110,
        "Reinforced Concrete Open Girder/Beam",
        Unit::Metres,
        RC,
    ),
    element(202, "Steel Column", Unit::Each, Cracking::Steel),
    element(204, "Prestressed Concrete Column", Unit::Each, PSC),
    element(205, "Reinforced Concrete Column", Unit::Each, RC),
    element(210, "Reinforced Concrete Pier Wall", Unit::Metres, RC),
    element(215, "Reinforced Concrete Abutment", Unit::Metres, RC),
    element(231, "Steel Pier Cap", Unit::Metres, Cracking::Steel),
    element(233, "Prestressed Concrete Pier Cap", Unit::Metres, PSC),
    element(234, "Reinforced Concrete Pier Cap", Unit::Metres, RC),
];

const fn element(number: u16, name: &'static str, unit: Unit, cracking: Cracking) -> AashtoElement {
    AashtoElement {
        number,
        name,
        unit,
        cracking,
    }
}

/// The element numbered `number`, if postflight records it.
pub fn element_numbered(number: u16) -> Option<&'static AashtoElement> {
    ELEMENTS.iter().find(|e| e.number == number)
}

/// The numbers postflight records, as an error lists them.
pub fn numbers() -> String {
    let numbers: Vec<String> = ELEMENTS.iter().map(|e| e.number.to_string()).collect();
    numbers.join(", ")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_are_unique_and_defects_follow_the_material() {
        for (i, e) in ELEMENTS.iter().enumerate() {
            assert!(ELEMENTS[..i].iter().all(|o| o.number != e.number));
        }
        assert_eq!(element_numbered(12).unwrap().cracking.defect().number, 1130);
        assert_eq!(
            element_numbered(109).unwrap().cracking.defect().number,
            1110
        );
        assert_eq!(
            element_numbered(107).unwrap().cracking.defect().number,
            1010
        );
        assert_eq!(element_numbered(205).unwrap().unit, Unit::Each);
        assert!(element_numbered(1130).is_none());
    }
}
