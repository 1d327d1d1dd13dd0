/* Each MPI process gives hocurve its own share of a mesh
 * (hoc_mesh_create_distributed), with its own projector, curves it with the
 * other processes, and writes what its handle then holds.
 *
 *   mpirun -np N distributed DIR ORDER OPTIMIZE FAIL_RANK [ZERO_RANK [NULL_RANK]]
 *
 * DIR/part.R.txt is process R's share (written by test_distributed.py):
 *   dim n_vertices n_cells n_facets n_shapes
 *   n_vertices lines: global_id x y [z]
 *   n_cells lines:    dim + 1 local vertex indices
 *   n_facets lines:   dim local vertex indices, entity tag
 *   n_shapes lines:   tag cx cy cz r   (a circle or sphere: the projector)
 * The process FAIL_RANK (-1: none) has a projector that always fails; the
 * process ZERO_RANK (if given) asks for 0 increments; the process NULL_RANK
 * (if given) passes NULL for the handle's address to the create call.
 *
 * DIR/out.R.txt gets:
 *   status
 *   the handle's last error message (a line, maybe empty)
 *   unchanged: 1 if the mesh after the run is the mesh before (on failure)
 * and after a successful run:
 *   n_nodes n_cells nodes_per_cell min_q3 n_invalid n_certified_invalid, and
 *   (distributed.c only) increments taken, step backs, solves, fallbacks,
 *   caps removed, whether the optimisation ran
 *   n_nodes lines: global node index, owner, position (the native node set:
 *                  a node's own, where gmsh's is evaluated cell by cell)
 *   n_cells lines: the host's global ids of the cell's vertices (-1 for a
 *                  vertex the repair made), then its nodes' coordinates in
 *                  gmsh's order
 */
#include <math.h>
#include <mpi.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "hocurve.h"

typedef struct {
    int n;
    int *tags;
    double *shape; /* cx cy cz r per shape */
    int dim;       /* of the mesh: the points' components */
    int fail;
} Shapes;

static int project(void *user, int entity_dim, int tag, size_t n, const double *in, double *out) {
    const Shapes *s = (const Shapes *)user;
    int dim = s->dim;
    (void)entity_dim;
    if (s->fail) return 7;
    for (int k = 0; k < s->n; k++) {
        if (s->tags[k] != tag) continue;
        const double *c = &s->shape[4 * k];
        for (size_t i = 0; i < n; i++) {
            double d = 0.0;
            for (int j = 0; j < dim; j++) d += (in[i * dim + j] - c[j]) * (in[i * dim + j] - c[j]);
            d = sqrt(d);
            if (d == 0.0) return 2;
            for (int j = 0; j < dim; j++) out[i * dim + j] = c[j] + c[3] * (in[i * dim + j] - c[j]) / d;
        }
        return 0;
    }
    return 1;
}

static void *must(void *p) {
    if (!p) {
        fprintf(stderr, "out of memory\n");
        MPI_Abort(MPI_COMM_WORLD, 3);
    }
    return p;
}

int main(int argc, char **argv) {
    int provided;
    MPI_Init_thread(&argc, &argv, MPI_THREAD_SERIALIZED, &provided);
    int rank;
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    if (argc < 5 || argc > 7) {
        fprintf(stderr, "usage: distributed DIR ORDER OPTIMIZE FAIL_RANK [ZERO_RANK [NULL_RANK]]\n");
        MPI_Abort(MPI_COMM_WORLD, 2);
    }
    int order = atoi(argv[2]), optimize = atoi(argv[3]), fail_rank = atoi(argv[4]);
    int zero_rank = argc >= 6 ? atoi(argv[5]) : -1, null_rank = argc == 7 ? atoi(argv[6]) : -1;
    char path[4096];
    snprintf(path, sizeof path, "%s/part.%d.txt", argv[1], rank);
    FILE *f = fopen(path, "r");
    if (!f) {
        fprintf(stderr, "cannot read %s\n", path);
        MPI_Abort(MPI_COMM_WORLD, 2);
    }
    int dim, nv, nc, nf;
    Shapes shapes = {0};
    if (fscanf(f, "%d %d %d %d %d", &dim, &nv, &nc, &nf, &shapes.n) != 5) MPI_Abort(MPI_COMM_WORLD, 2);
    int64_t *ids = must(malloc(sizeof(int64_t) * nv));
    double *coords = must(malloc(sizeof(double) * nv * dim));
    int64_t *cells = must(malloc(sizeof(int64_t) * nc * (dim + 1)));
    int64_t *facets = must(malloc(sizeof(int64_t) * (nf + 1) * dim));
    int32_t *tags = must(malloc(sizeof(int32_t) * (nf + 1)));
    shapes.tags = must(malloc(sizeof(int) * (shapes.n + 1)));
    shapes.shape = must(malloc(sizeof(double) * 4 * (shapes.n + 1)));
    int ok = 1;
    for (int i = 0; i < nv; i++) {
        ok &= fscanf(f, "%ld", (long *)&ids[i]) == 1;
        for (int j = 0; j < dim; j++) ok &= fscanf(f, "%lf", &coords[i * dim + j]) == 1;
    }
    for (int i = 0; i < nc * (dim + 1); i++) ok &= fscanf(f, "%ld", (long *)&cells[i]) == 1;
    for (int i = 0; i < nf; i++) {
        for (int j = 0; j < dim; j++) ok &= fscanf(f, "%ld", (long *)&facets[i * dim + j]) == 1;
        ok &= fscanf(f, "%d", &tags[i]) == 1;
    }
    for (int k = 0; k < shapes.n; k++) {
        ok &= fscanf(f, "%d", &shapes.tags[k]) == 1;
        for (int j = 0; j < 4; j++) ok &= fscanf(f, "%lf", &shapes.shape[4 * k + j]) == 1;
    }
    fclose(f);
    if (!ok) {
        fprintf(stderr, "%s is malformed\n", path);
        MPI_Abort(MPI_COMM_WORLD, 2);
    }
    shapes.fail = rank == fail_rank;
    shapes.dim = dim;

    HocMesh *mesh = NULL;
    HocStatus st = hoc_mesh_create_distributed(MPI_Comm_c2f(MPI_COMM_WORLD), dim, nv, coords, ids, nc, cells,
                                               rank == null_rank ? NULL : &mesh);
    if (st != HOC_OK) {
        /* Every process fails alike: write that, without a mesh. */
        snprintf(path, sizeof path, "%s/out.%d.txt", argv[1], rank);
        FILE *o = fopen(path, "w");
        if (!o) MPI_Abort(MPI_COMM_WORLD, 2);
        fprintf(o, "%d\n%s\n%d\n", st, hoc_mesh_last_error(NULL), mesh == NULL);
        fclose(o);
        MPI_Finalize();
        return 0;
    }
    if (hoc_mesh_set_boundary(mesh, nf, facets, tags) != HOC_OK ||
        hoc_mesh_set_projector(mesh, project, &shapes) != HOC_OK ||
        hoc_mesh_set_order(mesh, order, HOC_SPACING_OPTIMAL) != HOC_OK ||
        hoc_mesh_set_optimize(mesh, optimize) != HOC_OK) {
        fprintf(stderr, "rank %d: setting up: %s\n", rank, hoc_mesh_last_error(mesh));
        MPI_Abort(MPI_COMM_WORLD, 1);
    }
    size_t n_before;
    hoc_mesh_node_count(mesh, &n_before);
    double *before = must(malloc(sizeof(double) * n_before * dim));
    hoc_mesh_get_nodes(mesh, HOC_ORDERING_NATIVE, n_before, before);

    st = hoc_mesh_run_increments(mesh, rank == zero_rank ? 0 : HOC_DEFAULT_INCREMENTS);
    char message[4096];
    snprintf(message, sizeof message, "%s", hoc_mesh_last_error(mesh));

    size_t n_nodes, n_cells, npc;
    hoc_mesh_node_count(mesh, &n_nodes);
    hoc_mesh_cell_count(mesh, &n_cells, &npc);
    double *nodes = must(malloc(sizeof(double) * n_nodes * dim));
    hoc_mesh_get_nodes(mesh, HOC_ORDERING_NATIVE, n_nodes, nodes);
    int unchanged = n_nodes == n_before && memcmp(nodes, before, sizeof(double) * n_nodes * dim) == 0;

    snprintf(path, sizeof path, "%s/out.%d.txt", argv[1], rank);
    FILE *o = fopen(path, "w");
    if (!o) MPI_Abort(MPI_COMM_WORLD, 2);
    fprintf(o, "%d\n%s\n%d\n", st, message, unchanged);
    if (st == HOC_OK) {
        HocQuality q;
        hoc_mesh_quality(mesh, &q);
        size_t taken, step_backs, solves, fallbacks;
        HocRepair repair;
        HocOptimization opt;
        if (hoc_mesh_increment_count(mesh, &taken, &step_backs) != HOC_OK ||
            hoc_mesh_solve_count(mesh, &solves, &fallbacks) != HOC_OK ||
            hoc_mesh_repair_summary(mesh, &repair) != HOC_OK || hoc_mesh_optimization(mesh, &opt) != HOC_OK)
            MPI_Abort(MPI_COMM_WORLD, 1);
        fprintf(o, "%zu %zu %zu %.17g %zu %zu %zu %zu %zu %zu %zu %d\n", n_nodes, n_cells, npc, q.min_q3,
                q.n_invalid, q.n_certified_invalid, taken, step_backs, solves, fallbacks, repair.removed_caps,
                opt.ran);
        int64_t *global = must(malloc(sizeof(int64_t) * n_nodes));
        int *owner = must(malloc(sizeof(int) * n_nodes));
        int64_t *conn = must(malloc(sizeof(int64_t) * n_cells * npc));
        double *xyz = must(malloc(sizeof(double) * n_nodes * dim));
        if (hoc_mesh_get_global_nodes(mesh, n_nodes, global, owner) != HOC_OK ||
            hoc_mesh_get_cells(mesh, HOC_ORDERING_GMSH, n_cells * npc, conn) != HOC_OK ||
            hoc_mesh_get_nodes(mesh, HOC_ORDERING_GMSH, n_nodes, xyz) != HOC_OK)
            MPI_Abort(MPI_COMM_WORLD, 1);
        for (size_t i = 0; i < n_nodes; i++) {
            fprintf(o, "%ld %d", (long)global[i], owner[i]);
            for (int j = 0; j < dim; j++) fprintf(o, " %.17g", nodes[i * dim + j]);
            fprintf(o, "\n");
        }
        for (size_t c = 0; c < n_cells; c++) {
            /* gmsh's order starts with the vertices; the share's own
             * vertices are its first nodes, in the order it gave them. */
            for (int a = 0; a <= dim; a++) {
                int64_t n = conn[c * npc + a];
                fprintf(o, "%ld ", n < nv ? (long)ids[n] : -1L);
            }
            for (size_t a = 0; a < npc; a++)
                for (int j = 0; j < dim; j++) fprintf(o, " %.17g", xyz[conn[c * npc + a] * dim + j]);
            fprintf(o, "\n");
        }
        free(global);
        free(owner);
        free(conn);
        free(xyz);
    }
    fclose(o);
    hoc_mesh_destroy(&mesh);
    free(ids), free(coords), free(cells), free(facets), free(tags), free(before), free(nodes);
    free(shapes.tags), free(shapes.shape);
    MPI_Finalize();
    return 0;
}
