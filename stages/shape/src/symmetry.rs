//! An object's symmetry: the turns that leave it looking the same. Two
//! poses that differ by one are the same pose for every purpose here: an
//! estimate is right if it is right for either (as BOP's metrics score
//! it), and a candidate that differs from the best only by a symmetry is
//! not a rival.

use glam::{DMat3, DVec3};

/// Steps a continuous symmetry is sampled at (1°).
const CONTINUOUS_STEPS: usize = 360;

/// The turns about the object's centre, object frame (z up), that leave it
/// looking the same; the identity is left out.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Symmetry {
    turns: Vec<DMat3>,
}

impl Symmetry {
    /// No symmetry.
    pub fn none() -> Self {
        Symmetry::default()
    }

    /// Whether there is none.
    pub fn is_none(&self) -> bool {
        self.turns.is_empty()
    }

    /// The turns, the identity left out.
    pub fn turns(&self) -> &[DMat3] {
        &self.turns
    }

    /// The symmetry of these turns (the identity, if among them, dropped).
    pub fn of_turns(turns: impl IntoIterator<Item = DMat3>) -> Self {
        Symmetry {
            turns: turns
                .into_iter()
                .filter(|t| crate::rotation_angle_deg(t, &DMat3::IDENTITY) > 1e-6)
                .collect(),
        }
    }

    /// `AXIS:N`: every 1/N turn about the object's `x`, `y` or `z` axis
    /// through its centre (`z:2`: a half turn about the up axis),
    /// `AXIS:inf` for any turn about it, or `none`.
    pub fn parse(spec: &str) -> Result<Self, SymmetryError> {
        let spec = spec.trim().to_ascii_lowercase();
        if spec == "none" {
            return Ok(Symmetry::none());
        }
        let bad = || SymmetryError(spec.clone());
        let (axis, n) = spec.split_once(':').ok_or_else(bad)?;
        let axis = match axis {
            "x" => DVec3::X,
            "y" => DVec3::Y,
            "z" => DVec3::Z,
            _ => return Err(bad()),
        };
        let n = match n {
            "inf" => CONTINUOUS_STEPS,
            n => match n.parse::<usize>() {
                Ok(n) if (1..=CONTINUOUS_STEPS).contains(&n) => n,
                _ => return Err(bad()),
            },
        };
        Ok(Symmetry::about(axis, n))
    }

    /// Every 1/`n` turn about `axis`.
    pub fn about(axis: DVec3, n: usize) -> Self {
        Symmetry {
            turns: (1..n.max(1))
                .map(|i| {
                    DMat3::from_axis_angle(
                        axis.normalize(),
                        std::f64::consts::TAU * i as f64 / n as f64,
                    )
                })
                .collect(),
        }
    }

    /// Any turn about `axis`, sampled every degree.
    pub fn continuous(axis: DVec3) -> Self {
        Symmetry::about(axis, CONTINUOUS_STEPS)
    }

    /// The rotations that look like `rotation` (camera from object):
    /// itself first, then one per turn.
    pub fn equivalents(&self, rotation: &DMat3) -> impl Iterator<Item = DMat3> + '_ {
        let r = *rotation;
        std::iter::once(r).chain(self.turns.iter().map(move |t| r * *t))
    }

    /// The smallest angle between `a` and any rotation that looks like
    /// `b`, degrees.
    pub fn angle_deg(&self, a: &DMat3, b: &DMat3) -> f64 {
        self.equivalents(b)
            .map(|e| crate::rotation_angle_deg(a, &e))
            .fold(f64::INFINITY, f64::min)
    }

    /// The turns as bytes (nine f64 each, column-major, little-endian).
    pub fn to_bytes(&self) -> Vec<u8> {
        self.turns
            .iter()
            .flat_map(|t| t.to_cols_array())
            .flat_map(f64::to_le_bytes)
            .collect()
    }

    /// Reads [`Symmetry::to_bytes`]; `None` when the length is not a whole
    /// number of turns or a turn is not a rotation.
    pub fn from_bytes(bytes: &[u8]) -> Option<Self> {
        if !bytes.len().is_multiple_of(72) {
            return None;
        }
        let turns: Vec<DMat3> = bytes
            .chunks_exact(72)
            .map(|c| {
                let v: Vec<f64> = c
                    .chunks_exact(8)
                    .map(|b| f64::from_le_bytes(b.try_into().expect("8 bytes")))
                    .collect();
                DMat3::from_cols_slice(&v)
            })
            .collect();
        let rotation = |t: &DMat3| {
            (t.determinant() - 1.0).abs() < 1e-6
                && (*t * t.transpose() - DMat3::IDENTITY)
                    .to_cols_array()
                    .iter()
                    .all(|x| x.abs() < 1e-6)
        };
        turns.iter().all(rotation).then_some(Symmetry { turns })
    }
}

/// A symmetry that could not be read.
#[derive(Debug, thiserror::Error)]
#[error(
    "symmetry {0:?}: expected AXIS:N (x, y or z and the number of equal turns, e.g. z:2), AXIS:inf or none"
)]
pub struct SymmetryError(pub String);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_half_turn_makes_the_turned_pose_the_same() {
        let s = Symmetry::parse("z:2").unwrap();
        assert_eq!(s.turns().len(), 1);
        let r = DMat3::from_rotation_x(0.3);
        let turned = r * DMat3::from_rotation_z(std::f64::consts::PI);
        assert!(s.angle_deg(&turned, &r) < 1e-6);
        assert!((Symmetry::none().angle_deg(&turned, &r) - 180.0).abs() < 1e-6);
        let back = Symmetry::from_bytes(&s.to_bytes()).unwrap();
        assert_eq!(back, s);
        assert!(Symmetry::from_bytes(&[0; 71]).is_none());
        assert!(Symmetry::from_bytes(&[0; 72]).is_none());
        for bad in ["w:2", "z:0", "z", "z:two"] {
            assert!(Symmetry::parse(bad).is_err(), "{bad}");
        }
        assert_eq!(Symmetry::parse("z:inf").unwrap().turns().len(), 359);
    }
}
