//! VTK files: XML unstructured grids (.vtu) with Lagrange cells.
