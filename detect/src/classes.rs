//! A model's classes and the defect kinds they mean: by name (the model's
//! metadata, or the prompts), or as `[detect] class_kinds` says.

use postflight_core::defect_kind::DefectKind;
use postflight_core::kind::Named;

/// The classes of a model, each with the kind of defect it finds (`None`:
/// a class postflight ignores, as a segmenter's background).
#[derive(Debug, Clone, PartialEq)]
pub struct Classes {
    pub names: Vec<String>,
    pub kinds: Vec<Option<DefectKind>>,
    /// Said when no class names a kind and every class is taken as a crack.
    pub warning: Option<String>,
}

impl Classes {
    /// The kinds `names` mean, with `given` (`NAME=KIND` each, `KIND`
    /// `none` to ignore a class) over the names' own. A model none of
    /// whose classes names a kind (a detector prompted "fissure") finds
    /// cracks with every class, as postflight took every model before it
    /// knew other kinds.
    pub fn of(names: Vec<String>, given: &[String]) -> Result<Self, String> {
        let mut kinds: Vec<Option<DefectKind>> =
            names.iter().map(|n| DefectKind::of_class(n)).collect();
        for entry in given {
            let (name, kind) = parse_given(entry)?;
            let Some(i) = names.iter().position(|n| n == name) else {
                return Err(format!(
                    "[detect] class_kinds names class '{name}', which the model does not have (its classes: {}); name one of those",
                    names.join(", ")
                ));
            };
            kinds[i] = kind;
        }
        let mut warning = None;
        if given.is_empty() && kinds.iter().all(Option::is_none) {
            warning = Some(format!(
                "no class of the model ({}) names a defect kind: all are taken as cracks; say what each finds with [detect] class_kinds (NAME=KIND)",
                names.join(", ")
            ));
            kinds = vec![Some(DefectKind::Crack); names.len()];
        }
        Ok(Self {
            names,
            kinds,
            warning,
        })
    }

    /// The kind class `class` finds, if it finds one.
    pub fn kind(&self, class: u32) -> Option<DefectKind> {
        self.kinds.get(class as usize).copied().flatten()
    }

    /// The kinds the model finds, each once, in the kinds' order.
    pub fn finds(&self) -> Vec<DefectKind> {
        DefectKind::ALL
            .iter()
            .copied()
            .filter(|k| self.kinds.contains(&Some(*k)))
            .collect()
    }
}

/// One `NAME=KIND` of `[detect] class_kinds`.
fn parse_given(entry: &str) -> Result<(&str, Option<DefectKind>), String> {
    let (name, kind) = entry.split_once('=').ok_or_else(|| {
        format!("[detect] class_kinds entry '{entry}' is not NAME=KIND (as spalling=spall)")
    })?;
    let kind = kind.trim();
    if kind == "none" {
        return Ok((name.trim(), None));
    }
    let kind = DefectKind::named(kind).ok_or_else(|| {
        let names: Vec<&str> = DefectKind::ALL.iter().map(|k| k.as_str()).collect();
        format!(
            "[detect] class_kinds entry '{entry}': '{kind}' is none of {}, none",
            names.join(", ")
        )
    })?;
    Ok((name.trim(), Some(kind)))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(n: &[&str]) -> Vec<String> {
        n.iter().map(|s| s.to_string()).collect()
    }

    #[test]
    fn a_segmenters_background_is_ignored_and_its_classes_mean_kinds() {
        let c = Classes::of(names(&["background", "exposed_rebar", "spalling"]), &[]).unwrap();
        assert_eq!(
            c.kinds,
            vec![
                None,
                Some(DefectKind::ExposedRebar),
                Some(DefectKind::Spall)
            ]
        );
        assert_eq!(c.finds(), vec![DefectKind::Spall, DefectKind::ExposedRebar]);
        assert!(c.warning.is_none());
    }

    #[test]
    fn a_model_of_unknown_names_finds_cracks_and_says_so() {
        let c = Classes::of(names(&["fissure"]), &[]).unwrap();
        assert_eq!(c.kind(0), Some(DefectKind::Crack));
        assert!(c.warning.unwrap().contains("class_kinds"));
    }

    #[test]
    fn settings_name_what_each_class_finds() {
        let given = ["damage=spall".to_string(), "crack=none".to_string()];
        let c = Classes::of(names(&["crack", "damage"]), &given).unwrap();
        assert_eq!(c.kinds, vec![None, Some(DefectKind::Spall)]);
        for bad in ["damage", "damage=hole", "wall=spall"] {
            let e = Classes::of(names(&["crack", "damage"]), &[bad.to_string()]).unwrap_err();
            assert!(e.contains("class_kinds"), "{e}");
        }
    }
}
