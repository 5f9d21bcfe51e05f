//! The network: standardised inputs, one tanh hidden layer, a sigmoid
//! output; trained full-batch with Adam on the mean (optionally
//! class-weighted) cross-entropy of the paper's eq. 3 plus an L2 penalty.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Weights of a trained network, in `f32` for rating.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Network {
    /// Number of inputs.
    pub inputs: usize,
    /// Number of hidden units.
    pub hidden: usize,
    /// Per-input mean of the training data.
    pub mean: Vec<f32>,
    /// Per-input standard deviation of the training data (> 0).
    pub std: Vec<f32>,
    /// Hidden weights, `hidden` rows of `inputs`.
    pub w1: Vec<f32>,
    /// Hidden biases.
    pub b1: Vec<f32>,
    /// Output weights.
    pub w2: Vec<f32>,
    /// Output bias.
    pub b2: f32,
}

impl Network {
    /// Output logit for the raw (not yet standardised) input `x(i)`,
    /// `i < inputs`. Allocates nothing: each hidden unit is accumulated
    /// straight into the output.
    pub fn logit(&self, x: impl Fn(usize) -> f32) -> f32 {
        let mut out = self.b2;
        for h in 0..self.hidden {
            let row = &self.w1[h * self.inputs..(h + 1) * self.inputs];
            let mut z = self.b1[h];
            for (i, (&w, (&m, &s))) in row.iter().zip(self.mean.iter().zip(&self.std)).enumerate() {
                z += w * ((x(i) - m) / s);
            }
            out += self.w2[h] * libm::tanhf(z);
        }
        out
    }

    /// Probability that the input is of the positive class; 0 if the
    /// arithmetic broke down (NaN from absurd but finite weights or inputs).
    pub fn predict(&self, x: impl Fn(usize) -> f32) -> f32 {
        let p = sigmoid(self.logit(x));
        if p.is_nan() { 0.0 } else { p }
    }
}

/// The logistic function.
pub(crate) fn sigmoid(z: f32) -> f32 {
    1.0 / (1.0 + libm::expf(-z))
}

/// Optimisation settings of [`fit`].
pub(crate) struct FitSettings {
    pub hidden: usize,
    pub epochs: usize,
    pub learning_rate: f64,
    pub l2: f64,
    pub seed: u64,
    /// Weight of a positive and of a negative example.
    pub class_weights: (f64, f64),
}

/// Trains a network on `n = labels.len()` examples whose raw inputs are
/// the rows of `x` (`n × d`, row-major). Deterministic for a given seed.
/// `progress(epoch, loss)` is called after every epoch (1-based) with the
/// objective (weighted mean cross-entropy + L2) before that epoch's update.
pub(crate) fn fit(
    x: &[f32],
    labels: &[bool],
    d: usize,
    s: &FitSettings,
    progress: &mut dyn FnMut(usize, f64),
) -> Network {
    let n = labels.len();
    let h = s.hidden;

    // Standardisation.
    let mut mean = vec![0.0f64; d];
    for row in x.chunks_exact(d) {
        for (m, &v) in mean.iter_mut().zip(row) {
            *m += v as f64;
        }
    }
    mean.iter_mut().for_each(|m| *m /= n as f64);
    let mut var = vec![0.0f64; d];
    for row in x.chunks_exact(d) {
        for ((q, &m), &v) in var.iter_mut().zip(&mean).zip(row) {
            *q += (v as f64 - m).powi(2);
        }
    }
    let std: Vec<f64> = var
        .iter()
        .map(|&q| {
            let sd = (q / n as f64).sqrt();
            // A constant input carries no information: leave it unscaled.
            if sd > 1e-6 { sd } else { 1.0 }
        })
        .collect();
    let mean32: Vec<f32> = mean.iter().map(|&m| m as f32).collect();
    let std32: Vec<f32> = std.iter().map(|&v| v as f32).collect();
    // Standardise exactly as rating will (in f32), then train in f64.
    let xs: Vec<f64> = x
        .chunks_exact(d)
        .flat_map(|row| {
            row.iter()
                .zip(mean32.iter().zip(&std32))
                .map(|(&v, (&m, &sd))| ((v - m) / sd) as f64)
        })
        .collect();

    // Parameters, flattened: w1 (h × d), b1 (h), w2 (h), b2.
    let (o_b1, o_w2, o_b2) = (h * d, h * d + h, h * d + 2 * h);
    let np = o_b2 + 1;
    let mut p = vec![0.0f64; np];
    let mut rng = ChaCha8Rng::seed_from_u64(s.seed);
    // Glorot-uniform initialisation; biases start at zero.
    let a1 = (6.0 / (d + h) as f64).sqrt();
    for w in &mut p[..o_b1] {
        *w = rng.random_range(-a1..a1);
    }
    let a2 = (6.0 / (h + 1) as f64).sqrt();
    for w in &mut p[o_w2..o_b2] {
        *w = rng.random_range(-a2..a2);
    }

    let (wp, wn) = s.class_weights;
    let total_weight: f64 = labels.iter().map(|&l| if l { wp } else { wn }).sum();
    let mut grad = vec![0.0f64; np];
    let mut m1 = vec![0.0f64; np];
    let mut m2 = vec![0.0f64; np];
    let (beta1, beta2, eps) = (0.9f64, 0.999f64, 1e-8f64);
    let mut act = vec![0.0f64; h];

    let problem = Problem {
        xs: &xs,
        labels,
        d,
        h,
        class_weights: (wp / total_weight, wn / total_weight),
        l2: s.l2,
    };
    for epoch in 1..=s.epochs {
        let loss = problem.loss_grad(&p, &mut grad, &mut act);
        progress(epoch, loss);
        // Adam.
        let c1 = 1.0 - beta1.powi(epoch.min(i32::MAX as usize) as i32);
        let c2 = 1.0 - beta2.powi(epoch.min(i32::MAX as usize) as i32);
        for i in 0..np {
            m1[i] = beta1 * m1[i] + (1.0 - beta1) * grad[i];
            m2[i] = beta2 * m2[i] + (1.0 - beta2) * grad[i] * grad[i];
            let mh = m1[i] / c1;
            let vh = m2[i] / c2;
            p[i] -= s.learning_rate * mh / (vh.sqrt() + eps);
        }
    }

    Network {
        inputs: d,
        hidden: h,
        mean: mean32,
        std: std32,
        w1: p[..o_b1].iter().map(|&v| v as f32).collect(),
        b1: p[o_b1..o_w2].iter().map(|&v| v as f32).collect(),
        w2: p[o_w2..o_b2].iter().map(|&v| v as f32).collect(),
        b2: p[o_b2] as f32,
    }
}

/// The objective over standardised data: class-weighted mean
/// cross-entropy (eq. 3 divided by the total weight) plus L2.
struct Problem<'a> {
    xs: &'a [f64],
    labels: &'a [bool],
    d: usize,
    h: usize,
    /// Weight of a positive and of a negative example, normalised so that
    /// all weights sum to 1.
    class_weights: (f64, f64),
    l2: f64,
}

impl Problem<'_> {
    /// Objective at parameters `p` (w1, b1, w2, b2 flattened); writes its
    /// gradient into `grad`. `act` is scratch for the hidden layer.
    fn loss_grad(&self, p: &[f64], grad: &mut [f64], act: &mut [f64]) -> f64 {
        let (d, h) = (self.d, self.h);
        let (o_b1, o_w2, o_b2) = (h * d, h * d + h, h * d + 2 * h);
        grad.iter_mut().for_each(|g| *g = 0.0);
        let (w1, rest) = p.split_at(o_b1);
        let (b1, rest) = rest.split_at(h);
        let (w2, b2) = rest.split_at(h);
        let mut loss = 0.0f64;
        for (row, &label) in self.xs.chunks_exact(d).zip(self.labels) {
            let mut z2 = b2[0];
            for k in 0..h {
                let wr = &w1[k * d..(k + 1) * d];
                let z: f64 = b1[k] + wr.iter().zip(row).map(|(w, v)| w * v).sum::<f64>();
                act[k] = libm::tanh(z);
                z2 += w2[k] * act[k];
            }
            let y = if label { 1.0 } else { 0.0 };
            let w = if label {
                self.class_weights.0
            } else {
                self.class_weights.1
            };
            // Cross-entropy from the logit, stable for large |z2|:
            // -y ln σ(z) - (1-y) ln(1-σ(z)) = max(z,0) - y z + ln(1 + e^{-|z|}).
            loss += w * (z2.max(0.0) - y * z2 + libm::log1p(libm::exp(-z2.abs())));
            let pz = 1.0 / (1.0 + libm::exp(-z2));
            let dz2 = w * (pz - y);
            let (g_w1, g_rest) = grad.split_at_mut(o_b1);
            let (g_b1, g_rest) = g_rest.split_at_mut(h);
            let (g_w2, g_b2) = g_rest.split_at_mut(h);
            g_b2[0] += dz2;
            for k in 0..h {
                g_w2[k] += dz2 * act[k];
                let dz1 = dz2 * w2[k] * (1.0 - act[k] * act[k]);
                g_b1[k] += dz1;
                for (g, v) in g_w1[k * d..(k + 1) * d].iter_mut().zip(row) {
                    *g += dz1 * v;
                }
            }
        }
        // L2 on the weights, not the biases.
        for i in (0..o_b1).chain(o_w2..o_b2) {
            loss += 0.5 * self.l2 * p[i] * p[i];
            grad[i] += self.l2 * p[i];
        }
        loss
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The analytic gradient matches central finite differences of the
    /// objective, for every parameter, with class weights and L2 on.
    #[test]
    fn gradient_matches_finite_differences() {
        let (d, h) = (3, 4);
        let xs = [
            0.3, -1.2, 0.5, 1.0, 0.1, -0.7, -0.4, 0.9, 1.3, 0.0, -0.2, 0.6,
        ];
        let labels = [true, false, true, false];
        let problem = Problem {
            xs: &xs,
            labels: &labels,
            d,
            h,
            class_weights: (0.15, 0.35),
            l2: 0.03,
        };
        let np = h * d + 2 * h + 1;
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let p: Vec<f64> = (0..np).map(|_| rng.random_range(-1.0..1.0)).collect();
        let mut grad = vec![0.0; np];
        let mut act = vec![0.0; h];
        problem.loss_grad(&p, &mut grad, &mut act);
        let mut scratch = vec![0.0; np];
        for i in 0..np {
            let eps = 1e-6;
            let mut q = p.clone();
            q[i] += eps;
            let up = problem.loss_grad(&q, &mut scratch, &mut act);
            q[i] -= 2.0 * eps;
            let down = problem.loss_grad(&q, &mut scratch, &mut act);
            let numeric = (up - down) / (2.0 * eps);
            assert!(
                (numeric - grad[i]).abs() < 1e-7,
                "parameter {i}: analytic {} numeric {numeric}",
                grad[i]
            );
        }
    }

    fn settings(hidden: usize, epochs: usize, seed: u64) -> FitSettings {
        FitSettings {
            hidden,
            epochs,
            learning_rate: 0.01,
            l2: 0.0,
            seed,
            class_weights: (1.0, 1.0),
        }
    }

    #[test]
    fn training_reduces_the_loss_and_is_deterministic() {
        let x = [0.0f32, 1.0, 1.0, 0.0, 0.5, 0.5, 0.2, 0.9];
        let labels = [true, false, true, false];
        let mut losses = Vec::new();
        let a = fit(&x, &labels, 2, &settings(3, 200, 1), &mut |e, l| {
            assert_eq!(e, losses.len() + 1);
            losses.push(l)
        });
        assert_eq!(losses.len(), 200);
        assert!(
            losses[199] < 0.5 * losses[0],
            "{} -> {}",
            losses[0],
            losses[199]
        );
        let b = fit(&x, &labels, 2, &settings(3, 200, 1), &mut |_, _| {});
        assert_eq!(a, b);
        let c = fit(&x, &labels, 2, &settings(3, 200, 2), &mut |_, _| {});
        assert_ne!(a, c);
    }

    #[test]
    fn constant_inputs_are_not_scaled() {
        let x = [3.0f32, 1.0, 3.0, 2.0];
        let net = fit(&x, &[true, false], 2, &settings(2, 1, 0), &mut |_, _| {});
        assert_eq!(net.mean, vec![3.0, 1.5]);
        assert_eq!(net.std, vec![1.0, 0.5]);
    }
}
