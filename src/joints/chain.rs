//! The kinematic chain: which bone each bone moves relative to, and how far it may turn.
//!
//! Bones form a tree. The root is registered from the identity; every other bone's rotation
//! search and refinement start from its parent's motion, its plausible motion is bounded
//! relative to that parent, and a bone whose own evidence is weak may follow its parent
//! (crate::joints::confidence). The knee's table is the default; a table in the settings
//! (`[[init.chain]]` entries) replaces it, and `--label-map` renames its codes. The rotation
//! search turns about the knee's flexion axis, found from the bones named femur and tibia
//! (joint.rs): other joints need an axis finder of their own.

use crate::check::within;
use crate::error::{Error, Result};
use crate::labels as label;
use crate::volume::Labels;

/// One bone of the chain.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Link {
    /// Label code of the bone in the source's label map.
    pub label: u16,
    /// Its name in reports and file names.
    pub name: String,
    /// The bone it moves relative to; none for the root.
    #[serde(default)]
    pub parent: Option<u16>,
    /// Rotations about the joint's flexion axis, relative to the parent's motion, scored before
    /// refinement: from, to, step (degrees). None: refinement starts from the parent's motion.
    #[serde(default)]
    pub search_degrees: Option<[f64; 3]>,
    /// The largest plausible rotation relative to the parent (degrees); a motion beyond it is
    /// not kept.
    pub max_degrees: f64,
}

impl Link {
    fn new(
        label: u16,
        name: &str,
        parent: Option<u16>,
        search: Option<[f64; 3]>,
        max: f64,
    ) -> Self {
        Link {
            label,
            name: name.into(),
            parent,
            search_degrees: search,
            max_degrees: max,
        }
    }
}

/// The knee: the femur is the root; the tibia and the patella turn relative to it through the
/// whole range of flexion (the patella by about 0.7 of the tibia's angle); the fibula is bound
/// to the tibia at the proximal tibiofibular joint, which allows a few degrees at most.
pub fn knee() -> Vec<Link> {
    let flexion = Some([-30.0, 150.0, 4.0]);
    vec![
        Link::new(label::FEMUR, "femur", None, None, 0.0),
        Link::new(label::TIBIA, "tibia", Some(label::FEMUR), flexion, 160.0),
        Link::new(
            label::PATELLA,
            "patella",
            Some(label::FEMUR),
            flexion,
            160.0,
        ),
        Link::new(label::FIBULA, "fibula", Some(label::TIBIA), None, 8.0),
    ]
}

/// Rejects a chain that is not a tree of distinct bone codes with sensible ranges.
pub fn check(chain: &[Link]) -> Result<()> {
    let bad = |what: String| Err(Error::InvalidInput(format!("init.chain: {what}")));
    if chain.is_empty() {
        return bad("no bones".into());
    }
    for (i, link) in chain.iter().enumerate() {
        let who = format!("{} (label {})", link.name, link.label);
        if link.label == label::OUTSIDE {
            return bad(format!("{who}: label 0 is outside the body, not a bone"));
        }
        if chain[..i].iter().any(|l| l.label == link.label) {
            return bad(format!("{who} is listed twice"));
        }
        if !within(link.max_degrees, 0.0, 180.0) {
            return bad(format!("{who}: max_degrees must be 0 to 180"));
        }
        if let Some(range) = link.search_degrees {
            check_search(&who, range)?;
            if link.parent.is_none() {
                return bad(format!(
                    "{who}: the root is not searched (no parent to turn from)"
                ));
            }
        }
        if let Some(parent) = link.parent {
            if !chain.iter().any(|l| l.label == parent) {
                return bad(format!("{who}: parent {parent} is not in the chain"));
            }
        }
    }
    for link in chain {
        if ancestors(chain, link.label).any(|a| a == link.label) {
            return bad(format!("{} is its own ancestor", link.name));
        }
    }
    Ok(())
}

fn check_search(who: &str, [from, to, step]: [f64; 3]) -> Result<()> {
    let in_turn = |a: f64| within(a, -360.0, 360.0);
    if in_turn(from) && in_turn(to) && to >= from && step > 0.0 && (to - from) / step <= 1000.0 {
        return Ok(());
    }
    Err(Error::InvalidInput(format!(
        "init.chain: {who}: search_degrees must be from, to, step in degrees (-360 to 360) with \
         to >= from, step > 0 and at most 1000 steps"
    )))
}

/// `chain` with the label codes of a user's label map (`--label-map femur=1,tibia=3`): each
/// name must be a bone of the chain and each code distinct and non-zero. Bones the map does
/// not name are left out (a map's other codes — cartilage, menisci — are then not read as
/// bones), their children hanging on their nearest named ancestor; the root must be named.
pub fn relabelled(chain: &[Link], map: &[(String, u16)]) -> Result<Vec<Link>> {
    let bad = |what: String| Err(Error::InvalidInput(format!("--label-map: {what}")));
    for (i, (name, code)) in map.iter().enumerate() {
        if !chain.iter().any(|l| &l.name == name) {
            return bad(format!(
                "no bone named {name:?} in the kinematic chain ({})",
                names(chain)
            ));
        }
        if let Some((other, _)) = map[..i].iter().find(|(n, c)| n == name || c == code) {
            return bad(format!("{name}={code} repeats a name or a code ({other})"));
        }
    }
    let code_of = |name: &str| map.iter().find(|(n, _)| n == name).map(|(_, c)| *c);
    let mut out = Vec::new();
    for link in chain {
        let Some(code) = code_of(&link.name) else {
            continue;
        };
        let named = |a: u16| self::link(chain, a).and_then(|l| code_of(&l.name));
        let parent = ancestors(chain, link.label).find_map(named);
        if link.parent.is_some() && parent.is_none() {
            let root = ancestors(chain, link.label).last().unwrap_or(link.label);
            let root = self::link(chain, root).map_or("", |l| l.name.as_str());
            return bad(format!(
                "{} is named but the chain's root, {root}, is not",
                link.name
            ));
        }
        out.push(Link {
            label: code,
            parent,
            ..link.clone()
        });
    }
    check(&out)?;
    Ok(out)
}

/// The chain's bone names: "femur, tibia, …".
fn names(chain: &[Link]) -> String {
    let each: Vec<&str> = chain.iter().map(|l| l.name.as_str()).collect();
    each.join(", ")
}

/// The chain's bones that have voxels in `labels`, in chain order.
pub fn present(chain: &[Link], labels: &Labels) -> Vec<u16> {
    chain
        .iter()
        .map(|l| l.label)
        .filter(|code| labels.data.contains(code))
        .collect()
}

/// The chain's codes and names as a user reads them: "2 femur, 3 tibia, …".
pub fn described(chain: &[Link]) -> String {
    let each: Vec<String> = chain
        .iter()
        .map(|l| format!("{} {}", l.label, l.name))
        .collect();
    each.join(", ")
}

/// The link of `code`, if the chain has one.
pub fn link(chain: &[Link], code: u16) -> Option<&Link> {
    chain.iter().find(|l| l.label == code)
}

/// `code`'s parent, grandparent, … (stops after as many steps as the chain has links, so a
/// cycle cannot hang it).
fn ancestors(chain: &[Link], code: u16) -> impl Iterator<Item = u16> + '_ {
    let mut at = link(chain, code).and_then(|l| l.parent);
    std::iter::from_fn(move || {
        let here = at?;
        at = link(chain, here).and_then(|l| l.parent);
        Some(here)
    })
    .take(chain.len())
}

/// The parent `code` moves relative to among the bones registered: its nearest registered
/// ancestor (a knee without its tibia hangs the fibula on the femur), none for a root.
pub fn parent_among(chain: &[Link], code: u16, registered: &[u16]) -> Option<u16> {
    ancestors(chain, code).find(|a| registered.contains(a))
}

/// The order bones are registered in: every bone after its parent, otherwise in chain order.
/// Every registered bone must be in the chain.
pub fn registration_order(chain: &[Link], registered: &[u16]) -> Result<Vec<u16>> {
    if let Some(missing) = registered.iter().find(|c| link(chain, **c).is_none()) {
        return Err(Error::InvalidInput(format!(
            "bone label {missing} is registered but init.chain has no entry for it"
        )));
    }
    let depth = |c: u16| {
        ancestors(chain, c)
            .filter(|a| registered.contains(a))
            .count()
    };
    let mut order: Vec<u16> = chain
        .iter()
        .map(|l| l.label)
        .filter(|c| registered.contains(c))
        .collect();
    order.sort_by_key(|&c| depth(c));
    Ok(order)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_knee_chain_is_a_tree_registered_root_first() {
        let chain = knee();
        check(&chain).unwrap();
        assert_eq!(
            registration_order(&chain, &[5, 4, 3, 2]).unwrap(),
            [2, 3, 4, 5]
        );
        assert_eq!(parent_among(&chain, 5, &[2, 3, 5]), Some(3));
        assert_eq!(parent_among(&chain, 5, &[2, 5]), Some(2));
        assert_eq!(parent_among(&chain, 2, &[2, 3]), None);
        assert_eq!(registration_order(&chain, &[5, 2]).unwrap(), [2, 5]);
    }

    #[test]
    fn bad_chains_are_refused_naming_the_bone() {
        let mut cyclic = knee();
        cyclic[0].parent = Some(label::FIBULA);
        let err = check(&cyclic).unwrap_err().to_string();
        assert!(err.contains("own ancestor"), "{err}");
        let mut orphan = knee();
        orphan[3].parent = Some(9);
        assert!(check(&orphan).unwrap_err().to_string().contains("parent 9"));
        let mut twice = knee();
        twice[3].label = label::TIBIA;
        assert!(check(&twice).unwrap_err().to_string().contains("twice"));
        let mut backwards = knee();
        backwards[1].search_degrees = Some([10.0, -10.0, 1.0]);
        assert!(check(&backwards)
            .unwrap_err()
            .to_string()
            .contains("tibia (label 3): search_degrees"));
        let mut outside = knee();
        outside[2].label = 0;
        assert!(check(&outside)
            .unwrap_err()
            .to_string()
            .contains("outside the body"));
        assert!(registration_order(&knee(), &[2, 7])
            .unwrap_err()
            .to_string()
            .contains("label 7"));
    }

    #[test]
    fn a_label_map_renames_codes_and_leaves_out_unnamed_bones() {
        let map = |pairs: &[(&str, u16)]| -> Vec<(String, u16)> {
            pairs.iter().map(|(n, c)| (n.to_string(), *c)).collect()
        };
        // The cartilage layout: 1 femur, 3 tibia, 5 fibula; no patella.
        let chain =
            relabelled(&knee(), &map(&[("femur", 1), ("tibia", 3), ("fibula", 5)])).unwrap();
        let codes: Vec<(u16, Option<u16>)> = chain.iter().map(|l| (l.label, l.parent)).collect();
        assert_eq!(codes, [(1, None), (3, Some(1)), (5, Some(3))]);
        // Without the tibia the fibula hangs on the femur.
        let chain = relabelled(&knee(), &map(&[("femur", 7), ("fibula", 9)])).unwrap();
        assert_eq!(chain[1].parent, Some(7));
        let err = |pairs: &[(&str, u16)]| relabelled(&knee(), &map(pairs)).unwrap_err().to_string();
        assert!(err(&[("femor", 1)]).contains("no bone named \"femor\""));
        assert!(err(&[("femur", 1), ("tibia", 1)]).contains("repeats"));
        assert!(err(&[("femur", 1), ("femur", 2)]).contains("repeats"));
        assert!(err(&[("tibia", 3)]).contains("root, femur, is not"));
        assert!(err(&[("femur", 0)]).contains("label 0"));
    }
}
