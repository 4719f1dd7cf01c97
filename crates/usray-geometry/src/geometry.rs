//! The scene's geometry ([`Geometry`]): a list of objects, nearest-hit queries,
//! point-in-solid queries and the nested-media convention ([`MediumStack`]).

use crate::shapes::{
    cylinder::Cylinder, half_space::HalfSpace, hollow_cylinder::HollowCylinder, mesh::MeshInstance,
    slab::Slab, sphere::Sphere,
};
use crate::{GeometryError, Ray, Vec3};
use usray_ad::Real;

/// One object's shape.
#[derive(Clone, Debug)]
pub enum Shape<T> {
    /// A solid sphere.
    Sphere(Sphere<T>),
    /// A solid cylinder along `y`.
    Cylinder(Cylinder<T>),
    /// A tube along `y` (the wall is the solid).
    HollowCylinder(HollowCylinder<T>),
    /// A layer between two depths.
    Slab(Slab<T>),
    /// A half-space (flat interface).
    HalfSpace(HalfSpace<T>),
    /// A closed triangle mesh.
    Mesh(MeshInstance<T>),
}

impl<T: Real> Shape<T> {
    /// Values only (meshes share their data and BVH).
    pub fn to_f64(&self) -> Shape<f64> {
        match self {
            Shape::Sphere(s) => Shape::Sphere(s.to_f64()),
            Shape::Cylinder(s) => Shape::Cylinder(s.to_f64()),
            Shape::HollowCylinder(s) => Shape::HollowCylinder(s.to_f64()),
            Shape::Slab(s) => Shape::Slab(s.to_f64()),
            Shape::HalfSpace(s) => Shape::HalfSpace(s.to_f64()),
            Shape::Mesh(m) => Shape::Mesh(m.to_f64()),
        }
    }

    /// Point strictly inside the solid (values).
    pub fn contains(&self, p: [f64; 3]) -> bool {
        match self {
            Shape::Sphere(s) => s.contains(p),
            Shape::Cylinder(s) => s.contains(p),
            Shape::HollowCylinder(s) => s.contains(p),
            Shape::Slab(s) => s.contains(p),
            Shape::HalfSpace(s) => s.contains(p),
            Shape::Mesh(m) => m.contains(p),
        }
    }

    fn validate(&self) -> Result<(), GeometryError> {
        let bad = |shape, reason| Err(GeometryError::InvalidShape { shape, reason });
        match self {
            Shape::Sphere(s) if !s.is_valid() => {
                bad("sphere", "radius must be > 0 and all values finite")
            }
            Shape::Cylinder(s) if !s.is_valid() => {
                bad("cylinder", "radius must be > 0 and all values finite")
            }
            Shape::HollowCylinder(s) if !s.is_valid() => bad(
                "hollow cylinder",
                "need radius > 0, 0 < thickness_m < radius, all values finite",
            ),
            Shape::Slab(s) if !s.is_valid() => {
                bad("slab", "need z_top_m < z_bottom_m, both finite")
            }
            Shape::HalfSpace(s) if !s.is_valid() => {
                bad("half-space", "need a finite point and a non-zero normal")
            }
            Shape::Mesh(m) if !m.world_from_object.is_valid() => {
                bad("mesh", "transform not finite or zero scale")
            }
            _ => Ok(()),
        }
    }
}

macro_rules! impl_from_shape {
    ($t:ident, $v:ident) => {
        impl<T> From<$t<T>> for Shape<T> {
            fn from(s: $t<T>) -> Self {
                Shape::$v(s)
            }
        }
    };
}
impl_from_shape!(Sphere, Sphere);
impl_from_shape!(Cylinder, Cylinder);
impl_from_shape!(HollowCylinder, HollowCylinder);
impl_from_shape!(Slab, Slab);
impl_from_shape!(HalfSpace, HalfSpace);
impl_from_shape!(MeshInstance, Mesh);

/// A ray–surface hit with differentiable quantities.
///
/// `normal` is the unit **outward normal of the object's solid region** at the hit
/// (for a tube's inner surface it points towards the axis; for a mesh, out of the
/// closed mesh). The ray **enters** the object iff `dir · normal < 0` and exits
/// iff `> 0` (see [`Hit::entering`]).
#[derive(Clone, Copy, Debug)]
pub struct Hit<T> {
    /// Distance along the (unit) ray, metres.
    pub t: T,
    /// Hit point `origin + t·dir`, metres.
    pub point: Vec3<T>,
    /// Unit outward normal of the object's solid.
    pub normal: Vec3<T>,
    /// Index of the object in the [`Geometry`] (as returned by [`Geometry::add`]).
    pub object: usize,
    /// Which surface of the object: 0 for one-surface shapes and meshes; tube
    /// 0 = outer, 1 = inner; slab 0 = top, 1 = bottom.
    pub surface: u32,
    /// Triangle index for meshes, 0 otherwise.
    pub primitive: u32,
}

impl<T: Real> Hit<T> {
    /// True when the ray enters the object here (`dir · normal < 0`, values).
    #[inline]
    pub fn entering(&self, dir: &Vec3<T>) -> bool {
        dir.dot(self.normal).value() < 0.0
    }
}

/// The value-only identity of a hit, as found by [`Geometry::find`]: enough to
/// recompute the differentiable quantities in any scalar type with
/// [`Geometry::hit_from`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HitId {
    /// Distance, metres (f64 value).
    pub t: f64,
    /// Object index.
    pub object: usize,
    /// Surface index (see [`Hit::surface`]).
    pub surface: u32,
    /// Triangle index for meshes, 0 otherwise.
    pub primitive: u32,
    /// Which analytic root (position in the shape's root list); 0 for meshes.
    pub root: u32,
}

/// The geometry of a scene: objects indexed `0, 1, …` in the order added.
///
/// Hit finding runs on values (`f64` analytic roots; for meshes an `f32` BVH with
/// `f64` primitive tests); the winning hit's `t`, point and normal are then
/// recomputed in `T` from the differentiable parameters and the `T` ray.
///
/// # Nested media
/// The transport keeps, per ray, a [`MediumStack`] of the object indices it is
/// inside (innermost on top). At a hit on object `k`: if [`Hit::entering`], push
/// `k`; otherwise remove `k` (normally the top). The medium a ray travels in is
/// the top of the stack, or the background when empty; the medium on the far side
/// of a hit is `k` when entering, else what is below `k` after removal
/// ([`MediumStack::after_exit`]). Start a ray with
/// [`Geometry::stack_at`] (for probe rays in water, normally empty). Where objects
/// overlap, the one **added later** counts as inside the earlier one
/// ([`Geometry::innermost_containing`]); so add containers before their contents.
/// A tube's lumen is *outside* the tube (background or whatever encloses the tube).
#[derive(Clone, Debug)]
pub struct Geometry<T> {
    objects: Vec<Shape<T>>,
    values: Vec<Shape<f64>>,
}

impl<T: Real> Default for Geometry<T> {
    fn default() -> Self {
        Self::new()
    }
}

impl<T: Real> Geometry<T> {
    /// An empty geometry.
    pub fn new() -> Self {
        Self {
            objects: Vec::new(),
            values: Vec::new(),
        }
    }

    /// Add an object; returns its index (used in [`Hit::object`]). Parameters are
    /// validated (finite, radius > 0, …).
    pub fn add(&mut self, shape: impl Into<Shape<T>>) -> Result<usize, GeometryError> {
        let shape = shape.into();
        shape.validate()?;
        self.values.push(shape.to_f64());
        self.objects.push(shape);
        Ok(self.objects.len() - 1)
    }

    /// Number of objects.
    pub fn len(&self) -> usize {
        self.objects.len()
    }

    /// True when there is no object.
    pub fn is_empty(&self) -> bool {
        self.objects.is_empty()
    }

    /// The objects, by index.
    pub fn objects(&self) -> &[Shape<T>] {
        &self.objects
    }

    /// Find the nearest hit with `t ∈ [t_min, t_max]` (metres) on values only.
    ///
    /// Use a small positive `t_min` (e.g. `1e-9` m, far below a wavelength) for
    /// rays leaving a surface, so the surface just left is not hit again. Tangent
    /// rays count as misses. Non-finite rays never hit.
    pub fn find(&self, ray: &Ray<f64>, t_min: f64, t_max: f64) -> Option<HitId> {
        if !(ray.origin.is_finite() && ray.dir.is_finite()) {
            return None;
        }
        let mut best: Option<HitId> = None;
        let mut t_hi = t_max;
        for (k, shape) in self.values.iter().enumerate() {
            let roots = match shape {
                Shape::Sphere(s) => s.roots(ray),
                Shape::Cylinder(s) => s.roots(ray),
                Shape::HollowCylinder(s) => s.roots(ray),
                Shape::Slab(s) => s.roots(ray),
                Shape::HalfSpace(s) => s.roots(ray),
                Shape::Mesh(m) => {
                    if let Some(h) = m.find(ray, t_min, t_hi) {
                        if h.t <= t_hi {
                            t_hi = h.t;
                            best = Some(HitId {
                                t: h.t,
                                object: k,
                                surface: 0,
                                primitive: h.triangle,
                                root: 0,
                            });
                        }
                    }
                    continue;
                }
            };
            if let Some(i) = roots.nearest_in(t_min, t_hi) {
                let (t, surface) = roots.items[i];
                if best.is_none_or(|b| t < b.t) {
                    t_hi = t;
                    best = Some(HitId {
                        t,
                        object: k,
                        surface,
                        primitive: 0,
                        root: i as u32,
                    });
                }
            }
        }
        best
    }

    /// Recompute a found hit's `t`, point and normal in `T` from the `T` ray and
    /// the `T` parameters. `ray` must have the values `id` was found with.
    pub fn hit_from(&self, ray: &Ray<T>, id: &HitId) -> Hit<T> {
        let shape = &self.objects[id.object];
        let pick = |r: crate::shapes::Roots<T>| {
            let i = (id.root as usize).min(r.len.saturating_sub(1));
            if r.len == 0 {
                T::from_f64(id.t)
            } else {
                r.items[i].0
            }
        };
        let (t, normal) = match shape {
            Shape::Sphere(s) => {
                let t = pick(s.roots(ray));
                (t, s.normal_at(ray.at(t), id.surface))
            }
            Shape::Cylinder(s) => {
                let t = pick(s.roots(ray));
                (t, s.normal_at(ray.at(t), id.surface))
            }
            Shape::HollowCylinder(s) => {
                let t = pick(s.roots(ray));
                (t, s.normal_at(ray.at(t), id.surface))
            }
            Shape::Slab(s) => {
                let t = pick(s.roots(ray));
                (t, s.normal_at(ray.at(t), id.surface))
            }
            Shape::HalfSpace(s) => {
                let t = pick(s.roots(ray));
                (t, s.normal_at(ray.at(t), id.surface))
            }
            Shape::Mesh(m) => match m.hit_quantities(ray, id.primitive) {
                Some(tn) => tn,
                None => {
                    // Unreachable for a found hit (the triangle is non-degenerate
                    // in the same values); stay finite regardless.
                    let [a, b, c] = m.world_corners(id.primitive);
                    (T::from_f64(id.t), (b - a).cross(c - a).normalize())
                }
            },
        };
        Hit {
            t,
            point: ray.at(t),
            normal,
            object: id.object,
            surface: id.surface,
            primitive: id.primitive,
        }
    }

    /// Curvature (1/m) at `hit` of its surface's cut through the `xz` plane,
    /// signed against [`Hit::normal`]: positive where the solid is convex
    /// (a cylinder's or sphere's outside), negative where concave (a tube's
    /// inner surface), 0 on planes and on meshes (flat triangles). The 2-D
    /// transport's wavefront curvature changes by it at every interface.
    pub fn in_plane_curvature(&self, hit: &Hit<T>) -> T {
        let (p, surface) = (hit.point, hit.surface);
        match &self.objects[hit.object] {
            Shape::Sphere(s) => s.in_plane_curvature(p, surface),
            Shape::Cylinder(s) => s.in_plane_curvature(p, surface),
            Shape::HollowCylinder(s) => s.in_plane_curvature(p, surface),
            Shape::Slab(_) | Shape::HalfSpace(_) | Shape::Mesh(_) => T::zero(),
        }
    }

    /// Thickness (metres) of object `object` where it is a layer with the same
    /// medium on both sides: a tube's wall (its lumen holds the medium around
    /// it) or a slab; `None` for solids and meshes. The far surface lies
    /// `thickness` along the inward normal of either surface (radial for a
    /// tube, `z` for a slab).
    ///
    /// ```
    /// use usray_geometry::shapes::hollow_cylinder::HollowCylinder;
    /// use usray_geometry::{Geometry, Shape, Vec3};
    /// let mut g = Geometry::<f64>::new();
    /// let tube = HollowCylinder::new(Vec3::new(0.0, 0.0, 0.02), 5e-3, 0.15e-3);
    /// let k = g.add(Shape::HollowCylinder(tube)).unwrap();
    /// assert_eq!(g.layer_thickness(k), Some(0.15e-3));
    /// ```
    pub fn layer_thickness(&self, object: usize) -> Option<T> {
        match self.objects.get(object)? {
            Shape::HollowCylinder(s) => Some(s.thickness_m),
            Shape::Slab(s) => Some(s.z_bottom_m - s.z_top_m),
            Shape::Sphere(_) | Shape::Cylinder(_) | Shape::HalfSpace(_) | Shape::Mesh(_) => None,
        }
    }

    /// The nearest hit with `t ∈ [t_min, t_max]` (metres): [`Geometry::find`] on
    /// the ray's values, then [`Geometry::hit_from`] in `T`.
    pub fn intersect(&self, ray: &Ray<T>, t_min: f64, t_max: f64) -> Option<Hit<T>> {
        let id = self.find(&ray.to_f64(), t_min, t_max)?;
        Some(self.hit_from(ray, &id))
    }

    /// Point strictly inside object `object`'s solid (values). `false` for an
    /// index out of range.
    pub fn contains(&self, object: usize, p: [f64; 3]) -> bool {
        self.values.get(object).is_some_and(|s| s.contains(p))
    }

    /// The objects containing `p`, in index order (outermost first under the
    /// "later is inside" convention).
    pub fn containing(&self, p: [f64; 3]) -> Vec<usize> {
        (0..self.values.len())
            .filter(|&k| self.values[k].contains(p))
            .collect()
    }

    /// The innermost object containing `p` (the highest index among those that
    /// contain it), or `None` for the background medium.
    pub fn innermost_containing(&self, p: [f64; 3]) -> Option<usize> {
        (0..self.values.len())
            .rev()
            .find(|&k| self.values[k].contains(p))
    }

    /// The medium stack of a ray starting at `p` (objects containing it, outermost
    /// at the bottom).
    pub fn stack_at(&self, p: [f64; 3]) -> MediumStack {
        let mut s = MediumStack::new();
        for k in self.containing(p) {
            s.push(k);
        }
        s
    }
}

/// Maximum nesting depth of a [`MediumStack`].
pub const MEDIUM_STACK_DEPTH: usize = 8;

/// The object indices a ray is currently inside, innermost on top (fixed size,
/// `Copy`, no allocation). See the nested-media convention on [`Geometry`].
///
/// ```
/// use usray_geometry::MediumStack;
/// let mut s = MediumStack::new();
/// s.push(0);
/// s.push(3);
/// assert_eq!(s.top(), Some(3));
/// assert_eq!(s.after_exit(3), Some(0));
/// s.exit(3);
/// assert_eq!(s.top(), Some(0));
/// s.exit(0);
/// assert_eq!(s.top(), None); // background
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub struct MediumStack {
    len: u8,
    ids: [u32; MEDIUM_STACK_DEPTH],
}

impl MediumStack {
    /// Empty: the ray is in the background medium.
    pub fn new() -> Self {
        Self::default()
    }

    /// Enter object `k`. Returns false (and leaves the stack unchanged) when the
    /// stack is full.
    pub fn push(&mut self, k: usize) -> bool {
        if (self.len as usize) < MEDIUM_STACK_DEPTH {
            self.ids[self.len as usize] = k as u32;
            self.len += 1;
            true
        } else {
            false
        }
    }

    /// Leave object `k`: removes its topmost occurrence (normally the top). Returns
    /// false when `k` was not on the stack (e.g. a ray that started inside an
    /// object it was not told about); the stack is then unchanged.
    pub fn exit(&mut self, k: usize) -> bool {
        let n = self.len as usize;
        match self.ids[..n].iter().rposition(|&x| x as usize == k) {
            Some(i) => {
                self.ids.copy_within(i + 1..n, i);
                self.len -= 1;
                true
            }
            None => false,
        }
    }

    /// The current (innermost) object, `None` for the background.
    pub fn top(&self) -> Option<usize> {
        self.len
            .checked_sub(1)
            .map(|i| self.ids[i as usize] as usize)
    }

    /// The medium a ray would be in after leaving `k` (the stack top once `k` is
    /// removed), `None` for the background.
    pub fn after_exit(&self, k: usize) -> Option<usize> {
        let mut s = *self;
        s.exit(k);
        s.top()
    }

    /// Apply a hit: push when entering, exit otherwise. Returns the new top.
    pub fn cross(&mut self, object: usize, entering: bool) -> Option<usize> {
        if entering {
            self.push(object);
        } else {
            self.exit(object);
        }
        self.top()
    }

    /// Number of objects on the stack.
    pub fn len(&self) -> usize {
        self.len as usize
    }

    /// True in the background medium.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
}
