//! Rigid-body kinematics over any [`Scalar`]: 3-vectors, rotation
//! matrices, the kinetic energy of rotation — what the three-dimensional
//! scenes (`bicycle`, `coin-incline`) write their Lagrangians with.

use nonholo_core::scene::Scalar;

pub type V<D> = [D; 3];
pub type R<D> = [[D; 3]; 3];

/// A constant.
pub fn c<D: Scalar>(x: f64) -> D {
    D::from(x)
}

/// A constant vector.
pub fn vc<D: Scalar>(v: [f64; 3]) -> V<D> {
    [c(v[0]), c(v[1]), c(v[2])]
}

pub fn add<D: Scalar>(a: V<D>, b: V<D>) -> V<D> {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

pub fn sub<D: Scalar>(a: V<D>, b: V<D>) -> V<D> {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

pub fn scale<D: Scalar>(a: V<D>, s: D) -> V<D> {
    [a[0] * s, a[1] * s, a[2] * s]
}

pub fn dot<D: Scalar>(a: V<D>, b: V<D>) -> D {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

pub fn cross<D: Scalar>(a: V<D>, b: V<D>) -> V<D> {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// `r v`.
pub fn mv<D: Scalar>(r: &R<D>, v: V<D>) -> V<D> {
    [dot(r[0], v), dot(r[1], v), dot(r[2], v)]
}

/// `rᵀ v`.
pub fn mtv<D: Scalar>(r: &R<D>, v: V<D>) -> V<D> {
    [
        r[0][0] * v[0] + r[1][0] * v[1] + r[2][0] * v[2],
        r[0][1] * v[0] + r[1][1] * v[1] + r[2][1] * v[2],
        r[0][2] * v[0] + r[1][2] * v[1] + r[2][2] * v[2],
    ]
}

pub fn mm<D: Scalar>(a: &R<D>, b: &R<D>) -> R<D> {
    let mut out = [[c(0.0); 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            out[i][j] = a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j];
        }
    }
    out
}

/// Rotation by `a` about the unit axis `s` (Rodrigues).
pub fn rotation<D: Scalar>(s: [f64; 3], a: D) -> R<D> {
    let (sn, cs) = (a.sin(), a.cos());
    let k = c::<D>(1.0) - cs;
    let mut out = [[c(0.0); 3]; 3];
    let skew = [[0.0, -s[2], s[1]], [s[2], 0.0, -s[0]], [-s[1], s[0], 0.0]];
    for i in 0..3 {
        for j in 0..3 {
            let id = if i == j { cs } else { c(0.0) };
            out[i][j] = id + k * (s[i] * s[j]) + sn * skew[i][j];
        }
    }
    out
}

/// `½ ωᵀ I ω` for a symmetric inertia `I` in body axes.
pub fn spin<D: Scalar>(i: &[[f64; 3]; 3], w: V<D>) -> D {
    let mut e = c::<D>(0.0);
    for a in 0..3 {
        for b in 0..3 {
            e += w[a] * w[b] * i[a][b];
        }
    }
    e * 0.5
}

/// `½ ωᵀ I ω` of an axisymmetric wheel with axle `a` (unit), moments `ixx`
/// about a diameter and `iyy` about the axle.
pub fn wheel_spin<D: Scalar>(ixx: f64, iyy: f64, w: V<D>, a: V<D>) -> D {
    let along = dot(w, a);
    ((dot(w, w) - along * along) * ixx + along * along * iyy) * 0.5
}

/// Rotation by `a` about `x`.
pub fn rot_x<D: Scalar>(a: D) -> R<D> {
    let (z, o, (s, co)) = (c::<D>(0.0), c::<D>(1.0), (a.sin(), a.cos()));
    [[o, z, z], [z, co, -s], [z, s, co]]
}

/// Rotation by `a` about `y`.
pub fn rot_y<D: Scalar>(a: D) -> R<D> {
    let (z, o, (s, co)) = (c::<D>(0.0), c::<D>(1.0), (a.sin(), a.cos()));
    [[co, z, s], [z, o, z], [-s, z, co]]
}

/// Rotation by `a` about `z`.
pub fn rot_z<D: Scalar>(a: D) -> R<D> {
    let (z, o, (s, co)) = (c::<D>(0.0), c::<D>(1.0), (a.sin(), a.cos()));
    [[co, -s, z], [s, co, z], [z, z, o]]
}

/// Column `j` of `r` (the image of the `j`-th axis).
pub fn column<D: Scalar>(r: &R<D>, j: usize) -> V<D> {
    [r[0][j], r[1][j], r[2][j]]
}
