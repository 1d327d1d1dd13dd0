//! Analytic shapes (circles, spheres, cylinders, tori, planes, lines, NACA
//! 4-digit aerofoils), their closest-point maps, the CLI syntax that names
//! them, and [`ShapeProjector`], a [`Projector`] built from them.

use std::collections::HashMap;
use std::fmt;

use super::naca::Naca4;
use super::Projector;
use crate::{Error, Result};

/// An analytic curve or surface.
///
/// Vectors (`normal`, `axis`, `direction`) need not be unit: they are
/// normalised where used. [`Shape::parse`] validates its input; a shape built
/// by hand with a zero vector or a non-positive radius is the caller's
/// responsibility (its closest points may then be non-finite, which
/// [`ShapeProjector`] reports as an error).
#[derive(Debug, Clone, PartialEq)]
pub enum Shape {
    /// Circle in the plane z = 0 (2D curve).
    Circle { center: [f64; 2], radius: f64 },
    /// Circle in 3D: centre, normal of its plane, radius (3D curve).
    Circle3 { center: [f64; 3], normal: [f64; 3], radius: f64 },
    /// Sphere (surface).
    Sphere { center: [f64; 3], radius: f64 },
    /// Infinite circular cylinder whose axis passes through `point` along
    /// `axis` (surface).
    Cylinder { point: [f64; 3], axis: [f64; 3], radius: f64 },
    /// Ring torus: distance `major` from `center` to the tube centre circle
    /// (in the plane normal to `axis`), tube radius `minor < major` (surface).
    Torus { center: [f64; 3], axis: [f64; 3], major: f64, minor: f64 },
    /// Plane through `point` with normal `normal` (surface).
    Plane { point: [f64; 3], normal: [f64; 3] },
    /// Infinite straight line through `point` along `direction` (curve).
    Line { point: [f64; 3], direction: [f64; 3] },
    /// NACA 4-digit aerofoil `MPTT` in the plane z = 0 with the closed
    /// trailing edge, leading edge at `origin`, chord along +x (2D closed
    /// curve). See [`Naca4`].
    Naca4 { digits: [u8; 4], chord: f64, origin: [f64; 2] },
}

impl Shape {
    /// Parse the CLI syntax:
    /// `sphere:cx,cy,cz,r`, `circle:cx,cy,r`, `circle3:cx,cy,cz,nx,ny,nz,r`,
    /// `cylinder:px,py,pz,ax,ay,az,r`, `torus:cx,cy,cz,R,r` (axis z) or
    /// `torus:cx,cy,cz,ax,ay,az,R,r`, `plane:px,py,pz,nx,ny,nz`,
    /// `line:px,py,pz,dx,dy,dz`, `naca4:DDDD,chord,x0,y0`.
    ///
    /// The kind is case-insensitive; spaces around items are ignored.
    /// [`Shape`]'s `Display` writes this syntax back (round trip).
    ///
    /// ```
    /// use hocurve::geometry::Shape;
    /// let s = Shape::parse("sphere:0,0,0,0.5").unwrap();
    /// assert_eq!(s, Shape::Sphere { center: [0.0; 3], radius: 0.5 });
    /// assert_eq!(Shape::parse(&s.to_string()).unwrap(), s);
    /// ```
    pub fn parse(s: &str) -> Result<Shape> {
        let (kind, rest) =
            s.split_once(':').ok_or_else(|| bad_shape(s, "expected KIND:values, e.g. sphere:0,0,0,1".into()))?;
        let text = ShapeText {
            text: s,
            kind: kind.trim().to_ascii_lowercase(),
            items: rest.split(',').map(str::trim).collect(),
        };
        let shape = text.shape()?;
        shape.validate().map_err(|e| match e {
            Error::InvalidInput(m) => bad_shape(s, m),
            other => other,
        })?;
        Ok(shape)
    }

    /// Check that the shape is well defined: finite numbers, positive radii
    /// and chord, non-zero vectors, `minor < major`, and a NACA code with
    /// non-zero thickness and camber position set whenever camber is.
    pub fn validate(&self) -> Result<()> {
        let bad = |m: &str| Err(Error::InvalidInput(m.to_string()));
        let finite = |v: &[f64]| v.iter().all(|x| x.is_finite());
        let nonzero = |v: &[f64; 3]| norm(*v) > 0.0;
        let ok_numbers = match self {
            Shape::Circle { center, radius } => finite(center) && radius.is_finite(),
            Shape::Circle3 { center, normal, radius } => finite(center) && finite(normal) && radius.is_finite(),
            Shape::Sphere { center, radius } => finite(center) && radius.is_finite(),
            Shape::Cylinder { point, axis, radius } => finite(point) && finite(axis) && radius.is_finite(),
            Shape::Torus { center, axis, major, minor } => {
                finite(center) && finite(axis) && major.is_finite() && minor.is_finite()
            }
            Shape::Plane { point, normal } => finite(point) && finite(normal),
            Shape::Line { point, direction } => finite(point) && finite(direction),
            Shape::Naca4 { chord, origin, .. } => finite(origin) && chord.is_finite(),
        };
        if !ok_numbers {
            return bad("all numbers must be finite");
        }
        match self {
            Shape::Circle { radius, .. }
            | Shape::Circle3 { radius, .. }
            | Shape::Sphere { radius, .. }
            | Shape::Cylinder { radius, .. }
                if *radius <= 0.0 =>
            {
                bad("the radius must be positive")
            }
            Shape::Circle3 { normal, .. } | Shape::Plane { normal, .. } if !nonzero(normal) => {
                bad("the normal must be non-zero")
            }
            Shape::Cylinder { axis, .. } | Shape::Torus { axis, .. } if !nonzero(axis) => {
                bad("the axis must be non-zero")
            }
            Shape::Line { direction, .. } if !nonzero(direction) => bad("the direction must be non-zero"),
            Shape::Torus { major, minor, .. } if !(*minor > 0.0 && *minor < *major) => {
                bad("the torus radii must satisfy 0 < minor < major")
            }
            Shape::Naca4 { digits, chord, .. } => {
                if *chord <= 0.0 {
                    bad("the chord must be positive")
                } else {
                    Naca4::from_digits(*digits, *chord, [0.0, 0.0]).map(|_| ())
                }
            }
            _ => Ok(()),
        }
    }

    /// 1 for curves (circle, circle3, line, naca4), 2 for surfaces.
    pub fn entity_dim(&self) -> usize {
        match self {
            Shape::Circle { .. } | Shape::Circle3 { .. } | Shape::Line { .. } | Shape::Naca4 { .. } => 1,
            Shape::Sphere { .. } | Shape::Cylinder { .. } | Shape::Torus { .. } | Shape::Plane { .. } => 2,
        }
    }

    /// Closest point on the shape to `x` (three components; z = 0 for the 2D
    /// shapes `Circle` and `Naca4`, whatever the z of `x`).
    ///
    /// Where the closest point is not unique (a point on the axis of a
    /// cylinder, torus or circle, at a sphere centre) one of the closest
    /// points is returned; the result is finite for every finite `x` of a
    /// valid shape.
    pub fn closest_point(&self, x: [f64; 3]) -> [f64; 3] {
        match self {
            Shape::Circle { center, radius } => {
                let d = [x[0] - center[0], x[1] - center[1], 0.0];
                let u = unit_or(d, [1.0, 0.0, 0.0]);
                [center[0] + radius * u[0], center[1] + radius * u[1], 0.0]
            }
            Shape::Circle3 { center, normal, radius } => {
                let u = radial_direction(sub(x, *center), unit(*normal));
                add(*center, scale(*radius, u))
            }
            Shape::Sphere { center, radius } => {
                let u = unit_or(sub(x, *center), [1.0, 0.0, 0.0]);
                add(*center, scale(*radius, u))
            }
            Shape::Cylinder { point, axis, radius } => {
                let a = unit(*axis);
                let d = sub(x, *point);
                let t = dot(d, a);
                let u = radial_direction(d, a);
                add(add(*point, scale(t, a)), scale(*radius, u))
            }
            Shape::Torus { center, axis, major, minor } => {
                let a = unit(*axis);
                let e = radial_direction(sub(x, *center), a);
                let q = add(*center, scale(*major, e));
                let u = unit_or(sub(x, q), e);
                add(q, scale(*minor, u))
            }
            Shape::Plane { point, normal } => {
                let n = unit(*normal);
                sub(x, scale(dot(sub(x, *point), n), n))
            }
            Shape::Line { point, direction } => {
                let a = unit(*direction);
                add(*point, scale(dot(sub(x, *point), a), a))
            }
            Shape::Naca4 { digits, chord, origin } => match Naca4::from_digits(*digits, *chord, *origin) {
                Ok(foil) => {
                    let c = foil.closest_point([x[0], x[1]]);
                    [c[0], c[1], 0.0]
                }
                Err(_) => [f64::NAN; 3],
            },
        }
    }

    /// Unsigned distance from `x` to the shape, by a closed formula where one
    /// exists (independent of [`Shape::closest_point`]), else `|x − closest|`.
    pub fn distance(&self, x: [f64; 3]) -> f64 {
        match self {
            Shape::Circle { center, radius } => {
                let rho = (x[0] - center[0]).hypot(x[1] - center[1]);
                (rho - radius).hypot(x[2])
            }
            Shape::Circle3 { center, normal, radius } => {
                let n = unit(*normal);
                let d = sub(x, *center);
                let h = dot(d, n);
                let rho = norm(cross(d, n));
                (rho - radius).hypot(h)
            }
            Shape::Sphere { center, radius } => (norm(sub(x, *center)) - radius).abs(),
            Shape::Cylinder { point, axis, radius } => (norm(cross(sub(x, *point), unit(*axis))) - radius).abs(),
            Shape::Torus { center, axis, major, minor } => {
                let a = unit(*axis);
                let d = sub(x, *center);
                let h = dot(d, a);
                let rho = norm(cross(d, a));
                ((rho - major).hypot(h) - minor).abs()
            }
            Shape::Plane { point, normal } => dot(sub(x, *point), unit(*normal)).abs(),
            Shape::Line { point, direction } => norm(cross(sub(x, *point), unit(*direction))),
            Shape::Naca4 { .. } => norm(sub(x, self.closest_point(x))),
        }
    }
}

/// The error about the shape text `s`: `why` it is not a valid shape.
fn bad_shape(s: &str, why: String) -> Error {
    Error::InvalidInput(format!("shape \"{s}\": {why}"))
}

/// A shape's text split into its kind (lower case) and its comma-separated
/// items, for [`Shape::parse`].
struct ShapeText<'a> {
    text: &'a str,
    kind: String,
    items: Vec<&'a str>,
}

impl ShapeText<'_> {
    /// The error `why` about this text.
    fn bad(&self, why: String) -> Error {
        bad_shape(self.text, why)
    }

    /// The items from `from` on as finite numbers, as many as one of `counts` (`syntax` names them).
    fn numbers(&self, from: usize, counts: &[usize], syntax: &str) -> Result<Vec<f64>> {
        let v = self.items[from..]
            .iter()
            .map(|t| match t.parse::<f64>() {
                Ok(v) if v.is_finite() => Ok(v),
                Ok(_) => Err(self.bad(format!("\"{t}\" is not a finite number"))),
                Err(_) => Err(self.bad(format!("\"{t}\" is not a number"))),
            })
            .collect::<Result<Vec<f64>>>()?;
        if counts.contains(&v.len()) {
            Ok(v)
        } else {
            Err(self.bad(format!("{} expects {syntax}, got {} value(s)", self.kind, v.len())))
        }
    }

    /// The shape this text names, with its parameters (not yet validated).
    fn shape(&self) -> Result<Shape> {
        let shape = match self.kind.as_str() {
            "circle" => {
                let v = self.numbers(0, &[3], "cx,cy,r")?;
                Shape::Circle { center: [v[0], v[1]], radius: v[2] }
            }
            "circle3" => {
                let v = self.numbers(0, &[7], "cx,cy,cz,nx,ny,nz,r")?;
                Shape::Circle3 { center: [v[0], v[1], v[2]], normal: [v[3], v[4], v[5]], radius: v[6] }
            }
            "sphere" => {
                let v = self.numbers(0, &[4], "cx,cy,cz,r")?;
                Shape::Sphere { center: [v[0], v[1], v[2]], radius: v[3] }
            }
            "cylinder" => {
                let v = self.numbers(0, &[7], "px,py,pz,ax,ay,az,r")?;
                Shape::Cylinder { point: [v[0], v[1], v[2]], axis: [v[3], v[4], v[5]], radius: v[6] }
            }
            "torus" => {
                let v = self.numbers(0, &[5, 8], "cx,cy,cz,R,r or cx,cy,cz,ax,ay,az,R,r")?;
                let (axis, major, minor) =
                    if v.len() == 5 { ([0.0, 0.0, 1.0], v[3], v[4]) } else { ([v[3], v[4], v[5]], v[6], v[7]) };
                Shape::Torus { center: [v[0], v[1], v[2]], axis, major, minor }
            }
            "plane" => {
                let v = self.numbers(0, &[6], "px,py,pz,nx,ny,nz")?;
                Shape::Plane { point: [v[0], v[1], v[2]], normal: [v[3], v[4], v[5]] }
            }
            "line" => {
                let v = self.numbers(0, &[6], "px,py,pz,dx,dy,dz")?;
                Shape::Line { point: [v[0], v[1], v[2]], direction: [v[3], v[4], v[5]] }
            }
            "naca4" => self.naca4()?,
            kind => {
                return Err(self.bad(format!(
                    "unknown kind \"{kind}\" (expected circle, circle3, sphere, cylinder, \
                     torus, plane, line or naca4)"
                )))
            }
        };
        Ok(shape)
    }

    /// A NACA 4-digit aerofoil: the four digits, then chord, x0, y0.
    fn naca4(&self) -> Result<Shape> {
        let code = self.items[0];
        let b = code.as_bytes();
        if b.len() != 4 || !b.iter().all(u8::is_ascii_digit) {
            return Err(self.bad(format!("naca4 expects four digits first (e.g. 2412), got \"{code}\"")));
        }
        let digits = [b[0] - b'0', b[1] - b'0', b[2] - b'0', b[3] - b'0'];
        let v = self.numbers(1, &[3], "DDDD,chord,x0,y0 (3 numbers after the digits)")?;
        Ok(Shape::Naca4 { digits, chord: v[0], origin: [v[1], v[2]] })
    }
}

impl fmt::Display for Shape {
    /// Writes the CLI syntax read by [`Shape::parse`] (exact round trip).
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let list = |v: &[f64]| v.iter().map(|x| format!("{x}")).collect::<Vec<_>>().join(",");
        match self {
            Shape::Circle { center, radius } => {
                write!(f, "circle:{}", list(&[center[0], center[1], *radius]))
            }
            Shape::Circle3 { center, normal, radius } => {
                let mut v = center.to_vec();
                v.extend_from_slice(normal);
                v.push(*radius);
                write!(f, "circle3:{}", list(&v))
            }
            Shape::Sphere { center, radius } => {
                let mut v = center.to_vec();
                v.push(*radius);
                write!(f, "sphere:{}", list(&v))
            }
            Shape::Cylinder { point, axis, radius } => {
                let mut v = point.to_vec();
                v.extend_from_slice(axis);
                v.push(*radius);
                write!(f, "cylinder:{}", list(&v))
            }
            Shape::Torus { center, axis, major, minor } => {
                let mut v = center.to_vec();
                v.extend_from_slice(axis);
                v.extend_from_slice(&[*major, *minor]);
                write!(f, "torus:{}", list(&v))
            }
            Shape::Plane { point, normal } => {
                let mut v = point.to_vec();
                v.extend_from_slice(normal);
                write!(f, "plane:{}", list(&v))
            }
            Shape::Line { point, direction } => {
                let mut v = point.to_vec();
                v.extend_from_slice(direction);
                write!(f, "line:{}", list(&v))
            }
            Shape::Naca4 { digits, chord, origin } => {
                let code: String = digits.iter().map(|d| char::from(b'0' + d % 10)).collect();
                write!(f, "naca4:{code},{}", list(&[*chord, origin[0], origin[1]]))
            }
        }
    }
}

/// Analytic shapes keyed by geometric entity (`entity_dim`, `tag`); a
/// [`Projector`] over them.
///
/// ```
/// use hocurve::geometry::{Projector, Shape, ShapeProjector};
/// let mut p = ShapeProjector::new();
/// p.insert(1, Shape::Circle { center: [0.0, 0.0], radius: 0.5 });
/// let mut out = [[0.0; 3]];
/// p.project(1, 1, &[[2.0, 0.0, 0.0]], &mut out).unwrap();
/// assert_eq!(out[0], [0.5, 0.0, 0.0]);
/// assert!(p.project(2, 1, &[[2.0, 0.0, 0.0]], &mut out).is_err());
/// ```
#[derive(Debug, Clone, Default)]
pub struct ShapeProjector {
    shapes: HashMap<(usize, i32), Shape>,
}

impl ShapeProjector {
    /// An empty projector.
    pub fn new() -> Self {
        Self::default()
    }

    /// Attach `shape` to entity (`shape.entity_dim()`, `tag`), replacing any
    /// shape already there.
    pub fn insert(&mut self, tag: i32, shape: Shape) {
        self.shapes.insert((shape.entity_dim(), tag), shape);
    }

    /// The shape of entity (`entity_dim`, `tag`), if any.
    pub fn get(&self, entity_dim: usize, tag: i32) -> Option<&Shape> {
        self.shapes.get(&(entity_dim, tag))
    }

    /// Number of entities with a shape.
    pub fn len(&self) -> usize {
        self.shapes.len()
    }

    /// True when no entity has a shape.
    pub fn is_empty(&self) -> bool {
        self.shapes.is_empty()
    }

    /// All entities as ((`entity_dim`, `tag`), shape), in no particular order.
    pub fn iter(&self) -> impl Iterator<Item = (&(usize, i32), &Shape)> {
        self.shapes.iter()
    }
}

impl Projector for ShapeProjector {
    /// Closest points on the entity's shape. Errors (never panics) on an
    /// unknown entity, mismatched lengths, or a non-finite input or output.
    fn project(
        &self,
        entity_dim: usize,
        tag: i32,
        points: &[[f64; 3]],
        out: &mut [[f64; 3]],
    ) -> std::result::Result<(), String> {
        let shape = self
            .get(entity_dim, tag)
            .ok_or_else(|| format!("no analytic shape for the entity of dimension {entity_dim} with tag {tag}"))?;
        if points.len() != out.len() {
            return Err(format!("{} points but an output buffer of {}", points.len(), out.len()));
        }
        for (i, (x, o)) in points.iter().zip(out.iter_mut()).enumerate() {
            if !x.iter().all(|c| c.is_finite()) {
                return Err(format!("point {i} {x:?} (entity dim {entity_dim}, tag {tag}) is not finite"));
            }
            let y = shape.closest_point(*x);
            if !y.iter().all(|c| c.is_finite()) {
                return Err(format!(
                    "projecting point {i} {x:?} onto {shape} (entity dim {entity_dim}, \
                     tag {tag}) gave a non-finite point"
                ));
            }
            *o = y;
        }
        Ok(())
    }
}

pub(crate) fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

pub(crate) fn add(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

pub(crate) fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

pub(crate) fn scale(s: f64, a: [f64; 3]) -> [f64; 3] {
    [s * a[0], s * a[1], s * a[2]]
}

pub(crate) fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

pub(crate) fn norm(a: [f64; 3]) -> f64 {
    a[0].hypot(a[1]).hypot(a[2])
}

fn unit(a: [f64; 3]) -> [f64; 3] {
    scale(1.0 / norm(a), a)
}

/// `a / |a|`, or `fallback` when `a` is (numerically) zero.
pub(crate) fn unit_or(a: [f64; 3], fallback: [f64; 3]) -> [f64; 3] {
    let n = norm(a);
    if n > f64::MIN_POSITIVE && n.is_finite() {
        scale(1.0 / n, a)
    } else {
        fallback
    }
}

/// Unit vector along the part of `d` perpendicular to the unit vector `a`
/// (two Gram–Schmidt passes so that it is perpendicular to round-off), or
/// any unit vector perpendicular to `a` when `d` is along `a` to round-off.
fn radial_direction(d: [f64; 3], a: [f64; 3]) -> [f64; 3] {
    let v = sub(d, scale(dot(d, a), a));
    let v = sub(v, scale(dot(v, a), a));
    if norm(v) <= 8.0 * f64::EPSILON * norm(d) {
        any_perpendicular(a)
    } else {
        unit_or(v, any_perpendicular(a))
    }
}

/// A unit vector perpendicular to the unit vector `n`.
fn any_perpendicular(n: [f64; 3]) -> [f64; 3] {
    let i = (0..3).min_by(|&i, &j| n[i].abs().total_cmp(&n[j].abs())).unwrap_or(0);
    let mut e = [0.0; 3];
    e[i] = 1.0;
    unit(cross(n, e))
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::testing::Rng;

    /// A point of the cube of half-side `half` about `c`.
    fn point(rng: &mut Rng, c: [f64; 3], half: f64) -> [f64; 3] {
        [
            c[0] + half * (2.0 * rng.next() - 1.0),
            c[1] + half * (2.0 * rng.next() - 1.0),
            c[2] + half * (2.0 * rng.next() - 1.0),
        ]
    }

    fn frame(n: [f64; 3]) -> ([f64; 3], [f64; 3], [f64; 3]) {
        let n = unit(n);
        let e1 = any_perpendicular(n);
        (n, e1, cross(n, e1))
    }

    /// Dense sampling of the shape near `x` (a superset of where the closest
    /// point can be), for brute-force minimum distances.
    fn samples(shape: &Shape, x: [f64; 3]) -> Vec<[f64; 3]> {
        use std::f64::consts::PI;
        let m = 600;
        let mut out = Vec::new();
        let ang = |i: usize, m: usize| 2.0 * PI * i as f64 / m as f64;
        match shape {
            Shape::Circle { center, radius } => {
                for i in 0..20 * m {
                    let t = ang(i, 20 * m);
                    out.push([center[0] + radius * t.cos(), center[1] + radius * t.sin(), 0.0]);
                }
            }
            Shape::Circle3 { center, normal, radius } => {
                let (_, e1, e2) = frame(*normal);
                for i in 0..20 * m {
                    let t = ang(i, 20 * m);
                    out.push(add(*center, add(scale(radius * t.cos(), e1), scale(radius * t.sin(), e2))));
                }
            }
            Shape::Sphere { center, radius } => {
                for i in 0..=m {
                    let th = PI * i as f64 / m as f64;
                    for j in 0..2 * m {
                        let ph = ang(j, 2 * m);
                        out.push(add(*center, scale(*radius, [th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos()])));
                    }
                }
            }
            Shape::Cylinder { point, axis, radius } => {
                let (a, e1, e2) = frame(*axis);
                let t0 = dot(sub(x, *point), a);
                for i in 0..=m {
                    let t = t0 + 0.2 * (i as f64 / m as f64 - 0.5);
                    for j in 0..2 * m {
                        let ph = ang(j, 2 * m);
                        let r = add(scale(ph.cos(), e1), scale(ph.sin(), e2));
                        out.push(add(add(*point, scale(t, a)), scale(*radius, r)));
                    }
                }
            }
            Shape::Torus { center, axis, major, minor } => {
                let (a, e1, e2) = frame(*axis);
                for i in 0..2 * m {
                    let u = ang(i, 2 * m);
                    let e = add(scale(u.cos(), e1), scale(u.sin(), e2));
                    for j in 0..m {
                        let v = ang(j, m);
                        let p = add(scale(major + minor * v.cos(), e), scale(minor * v.sin(), a));
                        out.push(add(*center, p));
                    }
                }
            }
            Shape::Plane { point, normal } => {
                let (n, e1, e2) = frame(*normal);
                let foot = sub(x, scale(dot(sub(x, *point), n), n));
                for i in 0..=m {
                    for j in 0..=m {
                        let s = 0.02 * (i as f64 / m as f64 - 0.5);
                        let t = 0.02 * (j as f64 / m as f64 - 0.5);
                        out.push(add(foot, add(scale(s, e1), scale(t, e2))));
                    }
                }
            }
            Shape::Line { point, direction } => {
                let a = unit(*direction);
                let t0 = dot(sub(x, *point), a);
                for i in 0..=20 * m {
                    let t = t0 + 0.02 * (i as f64 / (20 * m) as f64 - 0.5);
                    out.push(add(*point, scale(t, a)));
                }
            }
            Shape::Naca4 { .. } => unreachable!("tested in naca.rs"),
        }
        out
    }

    fn test_shapes() -> Vec<Shape> {
        vec![
            Shape::Circle { center: [0.3, -0.2], radius: 0.7 },
            Shape::Circle3 { center: [0.1, 0.2, 0.3], normal: [1.0, 2.0, -0.5], radius: 0.6 },
            Shape::Sphere { center: [0.1, -0.3, 0.2], radius: 0.8 },
            Shape::Cylinder { point: [0.2, 0.1, -0.1], axis: [0.3, -1.0, 0.4], radius: 0.45 },
            Shape::Torus { center: [0.0, 0.1, -0.2], axis: [0.2, 0.3, 1.0], major: 0.9, minor: 0.3 },
            Shape::Plane { point: [0.1, 0.2, 0.3], normal: [-1.0, 0.5, 2.0] },
            Shape::Line { point: [0.1, 0.2, 0.3], direction: [1.0, -2.0, 0.7] },
        ]
    }

    #[test]
    fn closest_point_lies_on_shape_and_is_idempotent() {
        let mut rng = Rng(0x1234_5678_9abc_def1);
        for shape in test_shapes() {
            for _ in 0..200 {
                let x = point(&mut rng, [0.0; 3], 2.0);
                let y = shape.closest_point(x);
                assert!(
                    shape.distance(y) <= 1e-14 * 4.0,
                    "{shape}: closest {y:?} of {x:?} is {} off the shape",
                    shape.distance(y)
                );
                let z = shape.closest_point(y);
                assert!(norm(sub(z, y)) <= 1e-14 * 4.0, "{shape}: not idempotent");
                // The distance formula agrees with the closest point.
                let d = norm(sub(x, y));
                assert!((d - shape.distance(x)).abs() <= 1e-13, "{shape}: {d} vs formula");
            }
        }
    }

    #[test]
    fn closest_point_is_no_farther_than_dense_sampling() {
        let mut rng = Rng(0x0bad_cafe_dead_beef);
        for shape in test_shapes() {
            for _ in 0..3 {
                let x = point(&mut rng, [0.0; 3], 1.5);
                let d = norm(sub(x, shape.closest_point(x)));
                let brute = samples(&shape, x).iter().map(|s| norm(sub(x, *s))).fold(f64::INFINITY, f64::min);
                assert!(d <= brute + 1e-12, "{shape}: {d} > brute force {brute}");
                assert!(brute - d < 1e-2, "{shape}: sampling too coarse ({brute} vs {d})");
            }
        }
    }

    #[test]
    fn degenerate_points_give_a_valid_closest_point() {
        let cases = [
            (Shape::Sphere { center: [1.0, 2.0, 3.0], radius: 0.5 }, [1.0, 2.0, 3.0]),
            (Shape::Circle { center: [1.0, 2.0], radius: 0.5 }, [1.0, 2.0, 7.0]),
            (Shape::Circle3 { center: [1.0, 2.0, 3.0], normal: [0.0, 0.0, 2.0], radius: 0.5 }, [1.0, 2.0, -4.0]),
            (Shape::Cylinder { point: [0.0; 3], axis: [1.0, 1.0, 1.0], radius: 0.5 }, [2.0, 2.0, 2.0]),
            (Shape::Torus { center: [0.0; 3], axis: [0.0, 1.0, 0.0], major: 1.0, minor: 0.25 }, [0.0, 3.0, 0.0]),
            (Shape::Torus { center: [0.0; 3], axis: [0.0, 0.0, 1.0], major: 1.0, minor: 0.25 }, [0.0, 1.0, 0.0]),
        ];
        for (shape, x) in cases {
            let y = shape.closest_point(x);
            assert!(y.iter().all(|c| c.is_finite()), "{shape}: {y:?}");
            assert!(shape.distance(y) < 1e-14, "{shape}: {y:?} off the shape");
            let d = norm(sub(x, y));
            assert!((d - shape.distance(x)).abs() < 1e-14, "{shape}: not closest");
        }
    }

    #[test]
    fn parse_round_trips() {
        let mut all = test_shapes();
        all.push(Shape::Naca4 { digits: [2, 4, 1, 2], chord: 1.5, origin: [-0.25, 0.125] });
        all.push(Shape::Torus { center: [1e-7, -3.0, 0.1 + 0.2], axis: [0.0, 0.0, 1.0], major: 2.0, minor: 1.0 / 3.0 });
        for s in all {
            let text = s.to_string();
            assert_eq!(Shape::parse(&text).unwrap(), s, "{text}");
        }
        assert_eq!(
            Shape::parse(" Torus : 0, 0, 0, 2, 0.5").unwrap(),
            Shape::Torus { center: [0.0; 3], axis: [0.0, 0.0, 1.0], major: 2.0, minor: 0.5 }
        );
        assert_eq!(
            Shape::parse("naca4:0012,1,0,0").unwrap(),
            Shape::Naca4 { digits: [0, 0, 1, 2], chord: 1.0, origin: [0.0, 0.0] }
        );
    }

    #[test]
    fn parse_rejects_bad_strings() {
        let bad = [
            "",
            "sphere",
            "sphere:",
            "ellipse:0,0,1",
            "sphere:0,0,0",
            "sphere:0,0,0,1,2",
            "sphere:0,0,0,0",
            "sphere:0,0,0,-1",
            "sphere:0,0,nan,1",
            "sphere:0,0,inf,1",
            "sphere:0,0,x,1",
            "sphere:0,0,,1",
            "circle:0,0,0,1",
            "circle3:0,0,0,0,0,0,1",
            "cylinder:0,0,0,0,0,0,1",
            "cylinder:0,0,0,0,0,1,0",
            "torus:0,0,0,1,1",
            "torus:0,0,0,1,2",
            "torus:0,0,0,2,0",
            "torus:0,0,0,0,0,0,2,1",
            "torus:0,0,0,0,0,1,2",
            "plane:0,0,0,0,0,0",
            "line:0,0,0,0,0,0",
            "line:0,0,0,1,0",
            "naca4:241,1,0,0",
            "naca4:24a2,1,0,0",
            "naca4:2412,0,0,0",
            "naca4:2412,1,0",
            "naca4:2000,1,0,0",
            "naca4:2012,1,0,0",
        ];
        for s in bad {
            match Shape::parse(s) {
                Err(Error::InvalidInput(m)) => assert!(m.contains("shape"), "{s}: {m}"),
                other => panic!("\"{s}\" should be rejected, got {other:?}"),
            }
        }
    }

    #[test]
    fn entity_dims() {
        let dims: Vec<usize> = test_shapes().iter().map(Shape::entity_dim).collect();
        assert_eq!(dims, [1, 1, 2, 2, 2, 2, 1]);
    }

    #[test]
    fn projector_projects_and_reports_errors() {
        let mut p = ShapeProjector::new();
        p.insert(3, Shape::Sphere { center: [0.0; 3], radius: 2.0 });
        p.insert(3, Shape::Circle { center: [0.0; 2], radius: 1.0 });
        assert_eq!(p.len(), 2);
        assert!(p.get(2, 3).is_some() && p.get(1, 3).is_some() && p.get(2, 4).is_none());
        let pts = [[0.0, 0.0, 3.0], [4.0, 0.0, 0.0]];
        let mut out = [[0.0; 3]; 2];
        p.project(2, 3, &pts, &mut out).unwrap();
        assert_eq!(out, [[0.0, 0.0, 2.0], [2.0, 0.0, 0.0]]);
        p.project(1, 3, &pts, &mut out).unwrap();
        assert_eq!(out[1], [1.0, 0.0, 0.0]);

        let e = p.project(2, 7, &pts, &mut out).unwrap_err();
        assert!(e.contains("dimension 2") && e.contains("tag 7"), "{e}");
        assert!(p.project(2, 3, &pts, &mut out[..1]).is_err());
        assert!(p.project(2, 3, &[[f64::NAN, 0.0, 0.0]], &mut out[..1]).is_err());
        // A hand-built invalid shape gives an error, not a panic or NaN.
        p.insert(9, Shape::Plane { point: [0.0; 3], normal: [0.0; 3] });
        assert!(p.project(2, 9, &pts, &mut out).is_err());
    }
}
