//! The match-value response as a line plot in a 2-D view, like the
//! paper's figures 3 and 6: x is the database view index (θ slice by θ
//! slice, φ ascending within a slice), y the match value on a fixed 0..1
//! axis, with a separator and a label per θ slice. rerun has no line plot
//! over anything but time, so the plot is drawn as 2-D geometry: this
//! module computes it; [`crate::Logger`] logs it.

/// Plot units per view along x.
pub const DX: f32 = 4.0;
/// Plot units of the y axis (match value 0 at the bottom, 1 at the top).
pub const HEIGHT: f32 = 300.0;

/// One θ slice: a run of consecutive database views of the same θ.
#[derive(Clone, Debug, PartialEq)]
pub struct Slice {
    /// First view index.
    pub start: usize,
    /// Views in the run.
    pub len: usize,
    /// Elevation, degrees.
    pub theta_deg: f32,
}

/// The fixed geometry of the plot for one database, and the mapping of a
/// response onto it.
#[derive(Clone, Debug, PartialEq)]
pub struct ResponsePlot {
    /// (θ, φ) degrees of every view, database order.
    views: Vec<(f32, f32)>,
    /// The θ slices in database order.
    pub slices: Vec<Slice>,
}

impl ResponsePlot {
    /// The plot of a database whose views are `views` (θ, φ degrees, in
    /// database order).
    pub fn new(views: &[(f32, f32)]) -> ResponsePlot {
        let mut slices: Vec<Slice> = Vec::new();
        for (i, &(theta, _)) in views.iter().enumerate() {
            match slices.last_mut() {
                Some(s) if s.theta_deg == theta => s.len += 1,
                _ => slices.push(Slice {
                    start: i,
                    len: 1,
                    theta_deg: theta,
                }),
            }
        }
        ResponsePlot {
            views: views.to_vec(),
            slices,
        }
    }

    /// Views in the database.
    pub fn views(&self) -> usize {
        self.views.len()
    }

    /// Plot x of view `i`.
    pub fn x(i: usize) -> f32 {
        i as f32 * DX
    }

    /// Plot y of match value `v` (y grows downwards in a 2-D view; values
    /// outside 0..1 are drawn at the edge).
    pub fn y(v: f32) -> f32 {
        HEIGHT * (1.0 - v.clamp(0.0, 1.0))
    }

    /// The right end of the x axis.
    pub fn width(&self) -> f32 {
        Self::x(self.views.len().saturating_sub(1))
    }

    /// The response's polyline; `None` when it does not have one value per
    /// view. Non-finite values are drawn at 0.
    pub fn curve(&self, response: &[f32]) -> Option<Vec<[f32; 2]>> {
        (response.len() == self.views.len()).then(|| {
            response
                .iter()
                .enumerate()
                .map(|(i, &v)| [Self::x(i), Self::y(if v.is_finite() { v } else { 0.0 })])
                .collect()
        })
    }

    /// Index of the largest finite value (what winner-takes-all picks).
    pub fn best(response: &[f32]) -> Option<usize> {
        response
            .iter()
            .enumerate()
            .filter(|(_, v)| v.is_finite())
            .max_by(|a, b| a.1.total_cmp(b.1))
            .map(|(i, _)| i)
    }

    /// The view closest to (θ, φ) on the sphere (θ elevation): where the
    /// truth falls on the x axis.
    pub fn nearest_view(&self, theta_deg: f64, phi_deg: f64) -> Option<usize> {
        let dir = |t: f64, p: f64| {
            let (t, p) = (t.to_radians(), p.to_radians());
            [t.cos() * p.cos(), t.cos() * p.sin(), t.sin()]
        };
        let d = dir(theta_deg, phi_deg);
        self.views
            .iter()
            .map(|&(t, p)| {
                let v = dir(t as f64, p as f64);
                d[0] * v[0] + d[1] * v[1] + d[2] * v[2]
            })
            .enumerate()
            .max_by(|a, b| a.1.total_cmp(&b.1))
            .map(|(i, _)| i)
    }

    /// (θ, φ) of view `i`.
    pub fn view(&self, i: usize) -> Option<(f32, f32)> {
        self.views.get(i).copied()
    }

    /// Vertical separators between slices (half a view before each slice
    /// after the first).
    pub fn separators(&self) -> Vec<[[f32; 2]; 2]> {
        self.slices
            .iter()
            .skip(1)
            .map(|s| {
                let x = Self::x(s.start) - DX / 2.0;
                [[x, Self::y(1.0)], [x, Self::y(0.0)]]
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slices_are_runs_of_theta_in_database_order() {
        let views = [
            (30.0, 0.0),
            (30.0, 90.0),
            (60.0, 0.0),
            (60.0, 90.0),
            (60.0, 180.0),
            (90.0, 0.0),
        ];
        let p = ResponsePlot::new(&views);
        let runs: Vec<(usize, usize, f32)> = p
            .slices
            .iter()
            .map(|s| (s.start, s.len, s.theta_deg))
            .collect();
        assert_eq!(runs, vec![(0, 2, 30.0), (2, 3, 60.0), (5, 1, 90.0)]);
        // Separators sit between views 1|2 and 4|5.
        let xs: Vec<f32> = p.separators().iter().map(|s| s[0][0]).collect();
        assert_eq!(xs, vec![1.5 * DX, 4.5 * DX]);
    }

    #[test]
    fn the_curve_maps_values_onto_the_fixed_axis_and_the_best_is_the_maximum() {
        let p = ResponsePlot::new(&[(30.0, 0.0), (30.0, 90.0), (60.0, 0.0)]);
        let c = p.curve(&[0.0, 1.0, 0.25]).unwrap();
        assert_eq!(c, vec![[0.0, HEIGHT], [DX, 0.0], [2.0 * DX, 0.75 * HEIGHT]]);
        assert!(p.curve(&[0.5]).is_none(), "a short response is refused");
        assert_eq!(ResponsePlot::best(&[0.2, f32::NAN, 0.9, 0.4]), Some(2));
        assert_eq!(ResponsePlot::best(&[]), None);
    }

    #[test]
    fn the_nearest_view_wraps_in_phi_and_weighs_phi_by_elevation() {
        let p = ResponsePlot::new(&[(45.0, 0.0), (45.0, 180.0), (85.0, 90.0), (85.0, 270.0)]);
        // 350° is 10° from 0°, not 170° from 180°.
        assert_eq!(p.nearest_view(45.0, 350.0), Some(0));
        // Near the top, φ matters little: 80°/200° is closer to 85°/270°
        // than to 45°/180°.
        assert_eq!(p.nearest_view(80.0, 200.0), Some(3));
    }
}
