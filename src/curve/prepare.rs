//! The part of a run that needs neither the projector nor the mechanics: a
//! linear mesh validated and oriented, without its boundary caps, with its
//! topology, and elevated straight-sided to order p. [`Prepared`] is made
//! once and curved any number of times ([`super::curve_prepared`]); the
//! stateful [`crate::session::Session`] keeps one.

use crate::mesh::{remove_boundary_caps, validate_and_orient, HighOrderMesh, LinearMesh, Topology};
use crate::reference::{NodeSet, NodeSpacing};
use crate::{Error, Result};

use super::{validate_options, CurveOptions};

/// A linear mesh made ready to curve at one order ([`Prepared::new`]).
#[derive(Debug, Clone)]
pub struct Prepared {
    /// The mesh as given, validated and oriented, without its caps.
    linear: LinearMesh,
    /// For each cell of `linear`, its index in the mesh given.
    input_cell: Vec<usize>,
    n_input_cells: usize,
    /// Cells of the mesh given whose orientation was negative and was flipped.
    reoriented: usize,
    topo: Topology,
    nodes: NodeSet,
    /// `linear` elevated to the order, straight-sided.
    straight: HighOrderMesh,
    /// The options it was made for.
    order: usize,
    spacing: NodeSpacing,
    remove_caps: bool,
}

impl Prepared {
    /// Validate and orient `linear`, remove its boundary caps when
    /// `opts.remove_caps`, and elevate it to `opts.order` with
    /// `opts.spacing`. Fails on a malformed mesh or options.
    pub fn new(linear: &LinearMesh, opts: &CurveOptions) -> Result<Prepared> {
        let (oriented, reoriented) = validate_and_orient(linear)?;
        Prepared::from_oriented(oriented, reoriented, opts)
    }

    /// [`Prepared::new`] of a mesh that [`validate_and_orient`] has already
    /// passed and oriented (`reoriented`: the cells it flipped), without
    /// checking it again.
    pub fn from_oriented(oriented: LinearMesh, reoriented: usize, opts: &CurveOptions) -> Result<Prepared> {
        Prepared::from_oriented_after(oriented, reoriented, opts, None)
    }

    /// [`Prepared::from_oriented`], taking the topology of `previous` when
    /// the cells left to curve are the same (a host that tags the boundary
    /// and the feature edges after making the mesh changes tags only): the
    /// topology depends on the cells alone. 2.4 ms of the 5.3 of each
    /// preparation of a 6,000-cell STEP part.
    pub fn from_oriented_after(
        oriented: LinearMesh,
        reoriented: usize,
        opts: &CurveOptions,
        previous: Option<&Prepared>,
    ) -> Result<Prepared> {
        validate_options(opts)?;
        let n_input_cells = oriented.n_cells();
        let (linear, input_cell) =
            if opts.remove_caps { remove_boundary_caps(&oriented) } else { (oriented, (0..n_input_cells).collect()) };
        let same_cells = |p: &&Prepared| {
            (p.linear.dim, p.linear.n_vertices(), &p.linear.cells) == (linear.dim, linear.n_vertices(), &linear.cells)
        };
        let topo = match previous.filter(same_cells) {
            Some(p) => p.topo.clone(),
            None => Topology::new(&linear)?,
        };
        Prepared::elevated(linear, input_cell, n_input_cells, reoriented, topo, opts)
    }

    /// This mesh at the order and node spacing of `opts` (the same cap
    /// removal): elevated again, its orientation, caps and topology kept.
    pub fn at_order(&self, opts: &CurveOptions) -> Result<Prepared> {
        validate_options(opts)?;
        if opts.remove_caps != self.remove_caps {
            return Err(Error::InvalidInput("at_order keeps the cap removal; prepare the mesh anew".into()));
        }
        let (linear, topo) = (self.linear.clone(), self.topo.clone());
        Prepared::elevated(linear, self.input_cell.clone(), self.n_input_cells, self.reoriented, topo, opts)
    }

    fn elevated(
        linear: LinearMesh,
        input_cell: Vec<usize>,
        n_input_cells: usize,
        reoriented: usize,
        topo: Topology,
        opts: &CurveOptions,
    ) -> Result<Prepared> {
        let nodes = NodeSet::new(topo.simplex, opts.order, opts.spacing);
        let straight = HighOrderMesh::elevate(&linear, &topo, &nodes, opts.spacing)?;
        Ok(Prepared {
            linear,
            input_cell,
            n_input_cells,
            reoriented,
            topo,
            nodes,
            straight,
            order: opts.order,
            spacing: opts.spacing,
            remove_caps: opts.remove_caps,
        })
    }

    /// The linear mesh that is curved: the one given, oriented, less its caps.
    pub fn linear(&self) -> &LinearMesh {
        &self.linear
    }

    /// For each cell of [`Prepared::linear`], its index in the mesh given.
    pub fn input_cell(&self) -> &[usize] {
        &self.input_cell
    }

    /// Number of cells of the mesh given.
    pub fn n_input_cells(&self) -> usize {
        self.n_input_cells
    }

    /// Cells of the mesh given that were flipped to positive orientation.
    pub fn reoriented_cells(&self) -> usize {
        self.reoriented
    }

    pub fn topology(&self) -> &Topology {
        &self.topo
    }

    pub fn nodes(&self) -> &NodeSet {
        &self.nodes
    }

    /// [`Prepared::linear`] elevated to the order, straight-sided.
    pub fn straight_mesh(&self) -> &HighOrderMesh {
        &self.straight
    }

    /// Fails unless it was made for the order, node spacing and cap removal of `opts`.
    pub fn check_matches(&self, opts: &CurveOptions) -> Result<()> {
        if (self.order, self.spacing, self.remove_caps) != (opts.order, opts.spacing, opts.remove_caps) {
            return Err(Error::InvalidInput(format!(
                "the mesh was prepared for order {}, {:?} nodes and remove_caps {}; the options ask for order {}, \
                 {:?} nodes and remove_caps {}",
                self.order, self.spacing, self.remove_caps, opts.order, opts.spacing, opts.remove_caps
            )));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_new_order_elevates_the_prepared_mesh_again_and_keeps_the_rest() {
        // A flat boundary cap on two tets: removed or kept as asked.
        let m = crate::mesh::repair::caps::tests::ridge();
        for remove_caps in [true, false] {
            let at1 = Prepared::new(&m, &CurveOptions { order: 1, remove_caps, ..Default::default() }).unwrap();
            assert_eq!(at1.linear().n_cells(), if remove_caps { 2 } else { 3 });
            for (order, spacing) in [(3, NodeSpacing::Optimal), (2, NodeSpacing::Equispaced)] {
                let opts = CurveOptions { order, spacing, remove_caps, ..Default::default() };
                let (again, fresh) = (at1.at_order(&opts).unwrap(), Prepared::new(&m, &opts).unwrap());
                again.check_matches(&opts).unwrap();
                assert_eq!(again.linear(), fresh.linear());
                assert_eq!(again.input_cell(), fresh.input_cell());
                let (a, b) = (again.straight_mesh(), fresh.straight_mesh());
                assert_eq!(
                    (a.order, a.spacing, &a.cells, &a.constraint),
                    (b.order, b.spacing, &b.cells, &b.constraint)
                );
                assert!(a.coords.iter().zip(&b.coords).all(|(x, y)| x.to_bits() == y.to_bits()));
            }
            let other = CurveOptions { order: 2, remove_caps: !remove_caps, ..Default::default() };
            assert!(at1.at_order(&other).is_err());
            assert!(at1.at_order(&CurveOptions { order: 0, remove_caps, ..Default::default() }).is_err());
        }
    }

    /// `a` and `b` prepared alike: the same mesh, cells, topology and straight mesh, bit for bit.
    fn assert_same(a: &Prepared, b: &Prepared) {
        assert_eq!(a.linear(), b.linear());
        assert_eq!(a.input_cell(), b.input_cell());
        assert_eq!(a.topology(), b.topology());
        let (x, y) = (a.straight_mesh(), b.straight_mesh());
        assert_eq!((x.order, &x.cells, &x.constraint), (y.order, &y.cells, &y.constraint));
        assert!(x.coords.iter().zip(&y.coords).all(|(u, v)| u.to_bits() == v.to_bits()));
    }

    #[test]
    fn new_tags_on_the_same_cells_keep_the_topology_and_prepare_as_from_scratch() {
        let m = crate::mesh::repair::caps::tests::ridge();
        let opts = CurveOptions { order: 2, ..Default::default() };
        let previous = Prepared::new(&m, &opts).unwrap();
        assert_eq!(previous.linear().n_cells(), 2, "the cap is removed");
        // Other tags: the cap's two faces on one surface still (it is removed,
        // the same cells are left), or on two (it is kept: other cells).
        for (tags, cells) in [(vec![7, 7, 2, 2, 3, 3], 2), (vec![1, 2, 3, 4, 5, 6], 3)] {
            let retagged = LinearMesh { facet_tags: tags, ..m.clone() };
            let (oriented, _) = validate_and_orient(&retagged).unwrap();
            let after = Prepared::from_oriented_after(oriented, 0, &opts, Some(&previous)).unwrap();
            let fresh = Prepared::new(&retagged, &opts).unwrap();
            assert_eq!(after.linear().n_cells(), cells);
            assert_same(&after, &fresh);
        }
    }
}
