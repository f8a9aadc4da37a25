// dmmr-preprocess INPUT... -o SCENE_DIR
// An INPUT is a model file or a directory of them (read recursively).
#include <CLI/CLI.hpp>
#include <cstdio>
#include <utility>

#include "cli_options.h"
#include "error.h"
#include "preprocess.h"

int main(int argc, char** argv) {
  dmmr::PreprocessOptions o;
  CLI::App app{"dmmr-preprocess: split a model into a dmmr scene directory"};
  app.add_option("inputs", o.inputs,
                 "models (OBJ, PLY, OSGB, ... through OpenSceneGraph; glTF/GLB, FBX, 3MF, OFF "
                 "through assimp) or directories of them, read recursively")
      ->required();
  app.add_option("-o,--out", o.out, "scene directory to create (must not exist)")->required();
  app.add_option("--occluder-area-percentile", o.occluder_area_percentile,
                 "occluders: box face area at or above this percentile of all objects")
      ->check(CLI::Range(0.0, 100.0));
  app.add_option("--occluder-max-triangles", o.occluder_max_triangles,
                 "occluders: at most this many triangles");
  app.add_option("--lod-ratio", o.lod_ratio,
                 "occluder level of detail: target fraction of triangles (0: none)")
      ->check(CLI::Range(0.0, 1.0));
  app.add_option("--lod-error", o.lod_error, "occluder level of detail: relative error bound")
      ->check(CLI::Range(0.0, 1.0));
  app.add_option("--cluster-triangles", o.cluster_triangles,
                 "split meshes of more triangles than this into clusters of at most this many, "
                 "each its own object (0: keep meshes whole)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  dmmr::addSwitchOption(app, "--part-order", &o.part_order,
                        "on (each part box's triangles stored together, so that clients draw "
                        "only the parts that reach their region) or off (the input's triangle "
                        "order); never changes a pixel of the reference");
  std::string encoding = dmmr::encodingName(o.encoding);
  app.add_option("--encoding", encoding,
                 "geometry encoding: float32 (default, exact), meshopt (exact), quantized, "
                 "quantized-meshopt (lossy; see docs/scene-format.md)")
      ->check(CLI::Validator(
          [](std::string& name) {
            dmmr::Encoding e;
            return dmmr::parseEncoding(name, &e)
                       ? std::string()
                       : "unknown encoding '" + name +
                             "' (one of float32, meshopt, quantized, quantized-meshopt)";
          },
          "ENCODING"));
  app.add_flag("!--no-progress", o.progress, "do not print progress");
  app.add_flag("--skip-unreadable", o.skip_unreadable,
               "skip an input that cannot be read, with a warning naming it (default: error)");
  CLI11_PARSE(app, argc, argv);
  dmmr::parseEncoding(encoding, &o.encoding);  // checked above
  try {
    dmmr::PreprocessStats s = dmmr::preprocess(o);
    if (s.nonfinite_vertices)
      std::fprintf(stderr,
                   "dmmr-preprocess: warning: dropped %llu vertices with NaN or infinite "
                   "coordinates and the %llu triangles using them\n",
                   (unsigned long long)s.nonfinite_vertices,
                   (unsigned long long)s.dropped_triangles);
    // What was left out, one line each when it happened.
    const std::pair<uint64_t, const char*> warnings[] = {
        {s.bad_index_triangles, "dropped %llu triangles naming a vertex their mesh does not have"},
        {s.camera_fixed_subtrees,
         "skipped %llu subtrees under ABSOLUTE_RF transforms (fixed to the camera, like a HUD: "
         "not part of the model)"},
        {s.unloaded_lod_files,
         "%llu PagedLOD levels in files were not read (only the levels loaded with the model are "
         "taken)"},
        {s.billboards,
         "%llu billboards are drawn as modelled at their positions, not turned to face the eye"},
        {s.degenerate_triangles,
         "dropped %llu degenerate triangles (corners that coincide: they cover no pixel)"},
        {s.skipped_inputs, "skipped %llu unreadable inputs"},
        {s.skipped_drawables, "skipped %llu drawables without triangle geometry"},
    };
    for (const auto& [count, what] : warnings) {
      if (!count) continue;
      std::fprintf(stderr, "dmmr-preprocess: warning: ");
      std::fprintf(stderr, what, (unsigned long long)count);
      std::fprintf(stderr, "\n");
    }
    std::printf(
        "%s: %llu inputs, %llu objects, %llu geometries, %llu textures, %llu occluders, %llu "
        "triangles "
        "(%llu unique), %.1f MB, %.2f s (%.2f M triangles/s)\n",
        o.out.c_str(), (unsigned long long)s.inputs, (unsigned long long)s.objects,
        (unsigned long long)s.geometries, (unsigned long long)s.textures,
        (unsigned long long)s.occluders, (unsigned long long)s.triangles,
        (unsigned long long)s.unique_triangles, double(s.bytes_written) / 1e6, s.seconds,
        s.seconds > 0 ? double(s.triangles) / s.seconds / 1e6 : 0.0);
    if (o.encoding != dmmr::Encoding::Float32)
      std::printf("%s: geometry encoding %s\n", o.out.c_str(), dmmr::encodingName(o.encoding));
    if (s.split_meshes)
      std::printf("%s: %llu meshes split into clusters of at most %llu triangles\n", o.out.c_str(),
                  (unsigned long long)s.split_meshes, (unsigned long long)o.cluster_triangles);
    if (s.lod_geometries)
      std::printf("%s: occluder levels of detail for %llu geometries, %llu triangles\n",
                  o.out.c_str(), (unsigned long long)s.lod_geometries,
                  (unsigned long long)s.lod_triangles);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "dmmr-preprocess: %s\n", e.what());
    return 1;
  }
  return 0;
}
