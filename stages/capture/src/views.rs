//! Sets of views: the training grid and random test views.

use std::fmt;
use std::str::FromStr;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::{CaptureError, ViewPose};

/// A set of camera views on the hemisphere.
#[derive(Debug, Clone, PartialEq)]
pub enum ViewSpec {
    /// Every azimuth `0, step, 2 step, ... < 360` for each elevation in turn
    /// (ordered θ slice by θ slice). `grid:45,50,60,70,80,90:10` is the
    /// paper's training set of 216 views.
    Grid {
        /// Elevations in degrees, each in [0, 90].
        thetas_deg: Vec<f64>,
        /// Azimuth step in degrees, in (0, 360].
        phi_step_deg: f64,
    },
    /// `n` views with elevation uniform in [45, 90] and azimuth uniform in
    /// [0, 360), drawn from the seed.
    Random {
        /// Number of views.
        n: usize,
    },
}

impl ViewSpec {
    /// The paper's training grid, `grid:45,50,60,70,80,90:10`.
    pub fn training_grid() -> Self {
        ViewSpec::Grid {
            thetas_deg: vec![45.0, 50.0, 60.0, 70.0, 80.0, 90.0],
            phi_step_deg: 10.0,
        }
    }

    /// Azimuths of a grid slice.
    fn phis(step: f64) -> Vec<f64> {
        let n = 360.0 / step;
        // Exact divisors give n views; otherwise every k*step below 360.
        let count = if (n - n.round()).abs() < 1e-9 {
            n.round()
        } else {
            n.ceil()
        } as usize;
        (0..count)
            .map(|k| k as f64 * step)
            .filter(|&p| p < 360.0 - 1e-9)
            .collect()
    }

    /// The views, at camera distance `distance`; `seed` draws the random
    /// views (grids ignore it). The distance is not validated here: check it
    /// with [`crate::check_distance`].
    pub fn views(&self, distance: f64, seed: u64) -> Vec<ViewPose> {
        match self {
            ViewSpec::Grid {
                thetas_deg,
                phi_step_deg,
            } => {
                let phis = Self::phis(*phi_step_deg);
                thetas_deg
                    .iter()
                    .flat_map(|&theta_deg| {
                        phis.iter().map(move |&phi_deg| ViewPose {
                            theta_deg,
                            phi_deg,
                            distance,
                            roll_deg: 0.0,
                        })
                    })
                    .collect()
            }
            ViewSpec::Random { n } => {
                let mut rng = ChaCha8Rng::seed_from_u64(seed);
                (0..*n)
                    .map(|_| {
                        let theta_deg = 45.0 + 45.0 * rng.random::<f64>();
                        let phi_deg = 360.0 * rng.random::<f64>();
                        ViewPose {
                            theta_deg,
                            phi_deg,
                            distance,
                            roll_deg: 0.0,
                        }
                    })
                    .collect()
            }
        }
    }

    /// Number of views without generating them.
    pub fn len(&self) -> usize {
        match self {
            ViewSpec::Grid {
                thetas_deg,
                phi_step_deg,
            } => thetas_deg.len() * Self::phis(*phi_step_deg).len(),
            ViewSpec::Random { n } => *n,
        }
    }

    /// Whether the set is empty.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

impl FromStr for ViewSpec {
    type Err = CaptureError;
    /// Parses `grid:THETA,THETA,...:PHI_STEP` or `random:N`.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let err = |reason: String| CaptureError::InvalidViewSpec {
            spec: s.to_string(),
            reason,
        };
        let parts: Vec<&str> = s.trim().split(':').map(str::trim).collect();
        match parts.as_slice() {
            ["grid", thetas, step] => {
                let thetas_deg = thetas
                    .split(',')
                    .map(|t| {
                        let v: f64 = t
                            .trim()
                            .parse()
                            .map_err(|_| err(format!("elevation '{t}' is not a number")))?;
                        if (0.0..=90.0).contains(&v) {
                            Ok(v)
                        } else {
                            Err(err(format!("elevation {v} is outside [0, 90]")))
                        }
                    })
                    .collect::<Result<Vec<f64>, _>>()?;
                let phi_step_deg: f64 = step
                    .parse()
                    .map_err(|_| err(format!("azimuth step '{step}' is not a number")))?;
                if !(phi_step_deg > 0.0 && phi_step_deg <= 360.0) {
                    return Err(err(format!(
                        "azimuth step {phi_step_deg} must be in (0, 360]"
                    )));
                }
                Ok(ViewSpec::Grid {
                    thetas_deg,
                    phi_step_deg,
                })
            }
            ["random", n] => {
                let n: usize = n
                    .parse()
                    .map_err(|_| err(format!("view count '{n}' is not a whole number")))?;
                if n == 0 {
                    return Err(err("view count must be at least 1".to_string()));
                }
                Ok(ViewSpec::Random { n })
            }
            _ => Err(err("unrecognised form".to_string())),
        }
    }
}

impl fmt::Display for ViewSpec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ViewSpec::Grid {
                thetas_deg,
                phi_step_deg,
            } => {
                let t: Vec<String> = thetas_deg.iter().map(|t| t.to_string()).collect();
                write!(f, "grid:{}:{}", t.join(","), phi_step_deg)
            }
            ViewSpec::Random { n } => write!(f, "random:{n}"),
        }
    }
}
