// hocurve-occt: curve the linear mesh of a STEP/BREP model with hocurve, gmsh
// (OpenCASCADE) classifying every boundary facet and feature edge on its CAD
// entity and projecting onto it.
//
//   hocurve-occt MODEL.step|.brep --order P [--mesh-size H] [--curvature N] [--formulation F]
//                [--poisson NU] [--increments N] [--threads T] [--placement parametric|closest]
//                [--adaptive on|off] [--optimize on|off] [--tangent-first on|off] [--caps remove|keep]
//                [--retry on|off]
//                --output OUT.msh|.vtu [--report R.json]
#include "occt_pipeline.hpp"

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <iostream>
#include <optional>

namespace {

void usage() {
  std::cerr << "usage: hocurve-occt MODEL.step|.brep --order P [--mesh-size H] [--curvature N] [--formulation "
               "linear|ile|iil|cil|nonlinear] [--poisson NU] [--increments N] [--threads T] "
               "[--placement parametric|closest] [--adaptive on|off] [--optimize on|off] [--tangent-first on|off] "
               "[--caps remove|keep] "
               "[--retry on|off] --output OUT.msh|.vtu [--report R.json]\n";
}

HocFormulation parse_formulation(const std::string &s) {
  if (s == "linear") return HOC_FORMULATION_LINEAR;
  if (s == "ile") return HOC_FORMULATION_ILE;
  if (s == "iil") return HOC_FORMULATION_IIL;
  if (s == "cil") return HOC_FORMULATION_CIL;
  if (s == "nonlinear") return HOC_FORMULATION_NONLINEAR;
  throw std::runtime_error("unknown formulation '" + s + "'");
}

std::string json_number(double v) {
  if (!std::isfinite(v)) return "null";
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.15g", v);
  return buf;
}

/** `s` as the inside of a JSON string. */
std::string json_escape(const std::string &s) {
  std::string out;
  for (char c : s) {
    if (c == '"' || c == '\\') out += '\\', out += c;
    else if (static_cast<unsigned char>(c) < 0x20) {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\u%04x", c);
      out += buf;
    } else out += c;
  }
  return out;
}

/** The run's linear solves as a JSON array: which solver produced each
 *  solution, why the first choice did not ("none" when it did), iterations. */
std::string solves_json(const hocurve::Mesh &mesh) {
  std::string out = "[";
  for (const auto &s : mesh.solves()) {
    if (out.size() > 1) out += ", ";
    out += std::string("{\"solver\": \"") + s.solver_name() + "\", \"fallback\": \"" + s.fallback_name() +
           "\", \"iterations\": " + std::to_string(s.iterations) + "}";
  }
  return out + "]";
}

}  // namespace

int main(int argc, char **argv) {
  std::string model, output, report, formulation = "ile", placement = "parametric", adaptive = "on", optimize = "on",
              tangent_first = "on", caps = "remove", retry = "on";
  int order = 0, increments = 1, threads = 0, per_2pi = 12;
  double h = 0.0, poisson = 0.3;
  bool placement_given = false;
  for (int i = 1; i < argc; ++i) {
    std::string a = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) {
        usage();
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "--order") order = std::atoi(value().c_str());
    else if (a == "--mesh-size") h = std::atof(value().c_str());
    else if (a == "--formulation") formulation = value();
    else if (a == "--curvature") per_2pi = std::atoi(value().c_str());
    else if (a == "--poisson") poisson = std::atof(value().c_str());
    else if (a == "--increments") increments = std::atoi(value().c_str());
    else if (a == "--threads") threads = std::atoi(value().c_str());
    else if (a == "--placement") placement = value(), placement_given = true;
    else if (a == "--adaptive") adaptive = value();
    else if (a == "--optimize") optimize = value();
    else if (a == "--tangent-first") tangent_first = value();
    else if (a == "--caps") caps = value();
    else if (a == "--retry") retry = value();
    else if (a == "--output") output = value();
    else if (a == "--report") report = value();
    else if (a == "-h" || a == "--help") {
      usage();
      return 0;
    } else if (!a.empty() && a[0] != '-' && model.empty()) model = a;
    else {
      usage();
      return 2;
    }
  }
  if (model.empty() || output.empty() || order < 1 || (placement != "parametric" && placement != "closest") ||
      (adaptive != "on" && adaptive != "off") || (optimize != "on" && optimize != "off") ||
      (tangent_first != "on" && tangent_first != "off") ||
      (caps != "remove" && caps != "keep") || (retry != "on" && retry != "off")) {
    usage();
    return 2;
  }

  auto t0 = std::chrono::steady_clock::now();
  gmsh::initialize();
  gmsh::option::setNumber("General.Terminal", 0);
  int status = 0;
  try {
    occt::import_model(model);
    const int dim = occt::model_dim();
    occt::mesh_linear(dim, h, per_2pi);
    occt::LinearMesh lm = occt::collect(dim);
    auto t_mesh = std::chrono::steady_clock::now();

    const HocFormulation f = parse_formulation(formulation);
    // The incrementally linearised and nonlinear formulations need a hyperelastic material.
    const bool hyper = f == HOC_FORMULATION_IIL || f == HOC_FORMULATION_CIL || f == HOC_FORMULATION_NONLINEAR;
    occt::Projector proj;
    auto curve = [&]() {
      proj = occt::Projector{};
      proj.placement = placement == "closest" ? occt::Placement::Closest : occt::Placement::Parametric;
      hocurve::Mesh mesh = occt::make_mesh(lm, proj);
      mesh.set_material(hyper ? HOC_MATERIAL_NEO_HOOKEAN : HOC_MATERIAL_LINEAR_ELASTIC, 1e5, poisson);
      mesh.set_formulation(f);
      mesh.set_threads(threads);
      mesh.set_order(order);
      // Off: a step that inverts a cell is kept rather than halved, so the run
      // ends with the mesh and its invalid cells counted (exit status 3).
      if (adaptive == "off") mesh.set_adaptive_stepping(0);
      if (optimize == "off") mesh.set_optimize(false);
      // On by default: an OpenCASCADE projection costs microseconds, and
      // sliding in the tangent planes first projects a fraction as often.
      mesh.set_tangent_first(tangent_first == "on");
      if (caps == "keep") mesh.set_remove_caps(false);
      if (retry == "off") mesh.set_retry(false);
      mesh.run_increments(increments);
      return mesh;
    };
    // A run that cannot make every cell valid ("an element became
    // inverted") is tried again with the closest-point placement when the
    // command line left the placement to its default and --retry is on (it puts boundary
    // nodes at other places of the CAD). The library itself makes a run
    // that removed caps once more with the caps kept (SampleCrankshaft4A
    // at h = 112, p = 2 and 3 needs that); both go to stderr and the report.
    struct Retry {
      std::string change, after;
    };
    std::vector<Retry> retries;
    std::optional<hocurve::Mesh> curved;
    for (;;) {
      try {
        curved.emplace(curve());
        break;
      } catch (const hocurve::Error &e) {
        if (placement_given || placement != "parametric" || retry == "off" ||
            e.status() != HOC_ERROR_INVALID_ELEMENT)
          throw;
        std::fprintf(stderr, "hocurve-occt: %s\nhocurve-occt: trying again with placement closest\n", e.what());
        retries.push_back({"placement closest", e.what()});
        placement = "closest";
      }
    }
    if (const auto first = curved->caps_kept_after()) {
      std::fprintf(stderr, "hocurve-occt: the run was made again with the caps kept after: %s\n", first->c_str());
      retries.push_back({"caps keep", *first});
      caps = "keep";
    }
    hocurve::Mesh &mesh = *curved;
    auto t_curve = std::chrono::steady_clock::now();
    const HocQuality q = mesh.quality();
    const HocOptimization opt = mesh.optimization();
    const HocTimings tm = mesh.timings();
    const HocRepair rep = mesh.repair_summary();
    const auto cc = mesh.cell_count();
    const std::size_t nodes = mesh.node_count();
    mesh.write(output);
    auto t_end = std::chrono::steady_clock::now();
    auto secs = [](auto a, auto b) { return std::chrono::duration<double>(b - a).count(); };

    std::printf("%s: dim %d, %zu vertices, %zu cells given, %zu boundary facets, %zu feature edges; "
                "%zu caps removed, %zu edges split, %zu surface edges flipped, %zu cells curved\n",
                model.c_str(), dim, lm.coords.size() / dim, lm.cells.size() / (dim + 1), lm.facet_tags.size(),
                lm.edge_tags.size(), rep.removed_caps, rep.edge_splits, rep.surface_flips, cc.first);
    std::printf("p = %d: %zu nodes, min Q1 %.4f, min Q3 %.4f, mean Q3 %.4f, %zu invalid, %.2f s; wrote %s\n",
                order, nodes, q.min_q1, q.min_q3, q.mean_q3, q.n_invalid, secs(t0, t_end), output.c_str());
    for (const Retry &r : retries) std::printf("tried again with %s after: %s\n", r.change.c_str(), r.after.c_str());
    const occt::Placer *pl = proj.placer.get();
    if (pl && placement == "closest")
      std::printf("placement: closest point (%zu answers replaced by the local foot)\n", pl->closest_replaced);
    else if (pl)
      std::printf("placement: %zu nodes by closest point (%zu on no edge or facet, %zu seam, %zu too far; %zu "
                  "answers replaced by the local foot), %zu projected on %zu distorted facets (%zu facets at a pole, "
                  "%zu across a seam)\n",
                  pl->fallbacks, pl->fallbacks_unlocated, pl->fallbacks_seam, pl->fallbacks_far, pl->closest_replaced,
                  pl->projected, pl->distorted_facets, pl->pole_facets, pl->seam_facets);
    auto retries_json = [&] {
      std::string out;
      for (const Retry &r : retries)
        out += std::string(out.empty() ? "" : ", ") + "{\"change\": \"" + r.change + "\", \"after\": \"" +
               json_escape(r.after) + "\"}";
      return out;
    };
    if (!report.empty()) {
      std::ofstream r(report);
      r << "{\n  \"model\": \"" << json_escape(model) << "\",\n  \"dim\": " << dim << ",\n  \"order\": " << order
        << ",\n  \"formulation\": \"" << formulation << "\",\n  \"material\": \""
        << (hyper ? "neo-hookean" : "linear") << "\",\n  \"poisson\": " << json_number(poisson)
        << ",\n  \"increments\": " << increments << ",\n  \"adaptive\": \"" << adaptive << "\"" << ",\n  \"cells_given\": " << lm.cells.size() / (dim + 1)
        << ",\n  \"cells\": " << cc.first << ",\n  \"nodes\": " << nodes << ",\n  \"dofs\": " << nodes * dim
        << ",\n  \"boundary_facets\": " << lm.facet_tags.size() << ",\n  \"feature_edges\": "
        << lm.edge_tags.size() << ",\n  \"min_q1\": " << json_number(q.min_q1)
        << ",\n  \"min_q2\": " << json_number(q.min_q2) << ",\n  \"min_q3\": " << json_number(q.min_q3)
        << ",\n  \"mean_q3\": " << json_number(q.mean_q3) << ",\n  \"invalid_elements\": " << q.n_invalid
        << ",\n  \"placement\": \"" << placement << "\",\n  \"caps\": \"" << caps << "\",\n  \"retries\": ["
        << retries_json() << "],\n  \"placement_fallbacks\": " << (pl ? pl->fallbacks : 0)
        << ",\n  \"placement_fallback_reasons\": {\"unlocated\": " << (pl ? pl->fallbacks_unlocated : 0)
        << ", \"seam\": " << (pl ? pl->fallbacks_seam : 0) << ", \"far\": " << (pl ? pl->fallbacks_far : 0)
        << "},\n  \"closest_point_replaced\": " << (pl ? pl->closest_replaced : 0)
        << ",\n  \"placement_projected\": " << (pl ? pl->projected : 0)
        << ",\n  \"distorted_facets\": " << (pl ? pl->distorted_facets : 0)
        << ",\n  \"pole_facets\": " << (pl ? pl->pole_facets : 0) << ",\n  \"seam_facets\": " << (pl ? pl->seam_facets : 0)
        << ",\n  \"projector_calls\": " << proj.calls << ",\n  \"projector_points\": " << proj.points
        << ",\n  \"projector_seconds\": " << json_number(proj.seconds)
        << ",\n  \"repair\": {\"removed_caps\": " << rep.removed_caps << ", \"bad_cells\": " << rep.bad_cells << ", \"flips\": "
        << rep.flips_23 + rep.flips_32 + rep.edge_removals + rep.flips_22 << ", \"surface_caps\": " << rep.surface_caps
        << ", \"cells_removed\": " << rep.cells_removed << ", \"cells_added\": " << rep.cells_added
        << ", \"bad_cells_left\": " << rep.bad_cells_left
        << ", \"edge_splits\": " << rep.edge_splits << ", \"surface_flips\": " << rep.surface_flips << "}"
        << ",\n  \"elastic_stop\": " << (opt.elastic_stopped ? json_number(opt.elastic_load) : std::string("null"))
        << ",\n  \"elastic_restarted\": " << (opt.elastic_restarted ? "true" : "false")
        << ",\n  \"optimization\": {\"ran\": " << (opt.ran ? "true" : "false") << ", \"target_cells\": "
        << opt.target_cells << ", \"cells_touched\": " << opt.cells_touched << ", \"nodes_moved\": "
        << opt.nodes_moved << ", \"patches\": " << opt.patches << ", \"cells_split\": " << opt.cells_split << ", \"invalid_before\": " << opt.invalid_before
        << ", \"invalid_after\": " << opt.invalid_after << ", \"min_q3_before\": " << json_number(opt.min_q3_before)
        << ", \"min_q3_after\": " << json_number(opt.min_q3_after) << ", \"seconds\": " << json_number(opt.seconds)
        << "}"
        << ",\n  \"solver_fallbacks\": " << mesh.solver_fallbacks() << ",\n  \"solves\": " << solves_json(mesh)
        << ",\n  \"seconds\": {\"total\": "
        << json_number(secs(t0, t_end)) << ", \"mesh\": " << json_number(secs(t0, t_mesh))
        << ", \"curve\": " << json_number(secs(t_mesh, t_curve)) << ", \"stages\": {\"repair_and_elevate\": "
        << json_number(tm.repair_and_elevate) << ", \"place_boundary\": " << json_number(tm.place_boundary)
        << ", \"assembly\": " << json_number(tm.assembly) << ", \"solver_setup\": " << json_number(tm.solver_setup)
        << ", \"solve\": " << json_number(tm.solve) << ", \"check\": " << json_number(tm.check)
        << ", \"optimize\": " << json_number(tm.optimize) << ", \"quality\": " << json_number(tm.quality)
        << ", \"total\": " << json_number(tm.total) << "}}\n}\n";
      if (!r) throw std::runtime_error("cannot write " + report);
    }
    if (q.n_invalid > 0) status = 3;
  } catch (const std::exception &e) {
    std::cerr << "hocurve-occt: " << e.what() << "\n";
    status = 1;
  } catch (const std::string &s) {  // gmsh's API throws its error message
    std::cerr << "hocurve-occt: gmsh: " << s << "\n";
    status = 1;
  } catch (...) {
    std::cerr << "hocurve-occt: gmsh error\n";
    status = 1;
  }
  gmsh::finalize();
  return status;
}
