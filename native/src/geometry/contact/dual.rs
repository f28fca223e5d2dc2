//! Second-order forward differentiation over the 12 coordinates of a contact pair (four
//! points): each value carries its gradient and Hessian, so the barrier energy of a pair is
//! written once, as a formula, and its exact derivatives come with it (IPC, Li et al. 2020,
//! needs the Hessian of `kappa m(x) b(d^2)` for Newton; closed forms per distance type are
//! long and easy to get wrong).

use std::ops::{Add, Div, Mul, Neg, Sub};

/// Coordinates of a pair: four points, three each.
pub const N: usize = 12;

/// A value with its gradient and Hessian with respect to the pair's 12 coordinates.
#[derive(Clone, Copy, Debug)]
pub struct Dual {
    pub v: f64,
    pub g: [f64; N],
    pub h: [[f64; N]; N],
}

impl Dual {
    pub fn constant(v: f64) -> Self {
        Self { v, g: [0.0; N], h: [[0.0; N]; N] }
    }

    /// Coordinate `i` of the pair, at value `v`.
    pub fn variable(v: f64, i: usize) -> Self {
        let mut d = Self::constant(v);
        d.g[i] = 1.0;
        d
    }

    /// `f(self)` given `f`, `f'` and `f''` at `self.v` (the chain rule to second order).
    pub fn chain(&self, f: f64, df: f64, ddf: f64) -> Self {
        let mut out = Self::constant(f);
        for i in 0..N {
            out.g[i] = df * self.g[i];
            for j in 0..N {
                out.h[i][j] = df * self.h[i][j] + ddf * self.g[i] * self.g[j];
            }
        }
        out
    }

    pub fn ln(&self) -> Self {
        self.chain(self.v.ln(), 1.0 / self.v, -1.0 / (self.v * self.v))
    }

    pub fn scale(&self, s: f64) -> Self {
        let mut out = *self;
        out.v *= s;
        out.g.iter_mut().for_each(|x| *x *= s);
        out.h.iter_mut().flatten().for_each(|x| *x *= s);
        out
    }
}

impl Add for Dual {
    type Output = Dual;
    fn add(mut self, o: Dual) -> Dual {
        self.v += o.v;
        for i in 0..N {
            self.g[i] += o.g[i];
            for j in 0..N {
                self.h[i][j] += o.h[i][j];
            }
        }
        self
    }
}

impl Neg for Dual {
    type Output = Dual;
    fn neg(self) -> Dual {
        self.scale(-1.0)
    }
}

impl Sub for Dual {
    type Output = Dual;
    fn sub(self, o: Dual) -> Dual {
        self + (-o)
    }
}

impl Mul for Dual {
    type Output = Dual;
    fn mul(self, o: Dual) -> Dual {
        let mut out = Dual::constant(self.v * o.v);
        for i in 0..N {
            out.g[i] = self.g[i] * o.v + self.v * o.g[i];
            for j in 0..N {
                out.h[i][j] = self.h[i][j] * o.v + self.v * o.h[i][j] + self.g[i] * o.g[j] + o.g[i] * self.g[j];
            }
        }
        out
    }
}

impl Div for Dual {
    type Output = Dual;
    fn div(self, o: Dual) -> Dual {
        let inverse = o.chain(1.0 / o.v, -1.0 / (o.v * o.v), 2.0 / (o.v * o.v * o.v));
        self * inverse
    }
}

/// What the distance formulas need of a number: plain `f64` (the narrow phase, CCD) or
/// [`Dual`] (the barrier's derivatives), one formula for both.
pub trait Real: Copy + Add<Output = Self> + Sub<Output = Self> + Mul<Output = Self> + Div<Output = Self> {
    fn value(&self) -> f64;
}

impl Real for f64 {
    fn value(&self) -> f64 {
        *self
    }
}

impl Real for Dual {
    fn value(&self) -> f64 {
        self.v
    }
}

pub type Point<T> = [T; 3];

pub fn sub<T: Real>(a: Point<T>, b: Point<T>) -> Point<T> {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

pub fn dot<T: Real>(a: Point<T>, b: Point<T>) -> T {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

pub fn cross<T: Real>(a: Point<T>, b: Point<T>) -> Point<T> {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

/// The four points of a pair as [`Dual`] variables (coordinates 0..12 in order).
pub fn variables(points: &[[f64; 3]; 4]) -> [Point<Dual>; 4] {
    std::array::from_fn(|p| std::array::from_fn(|a| Dual::variable(points[p][a], 3 * p + a)))
}
