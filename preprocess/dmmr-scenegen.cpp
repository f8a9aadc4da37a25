// dmmr-scenegen: writes a generated test scene (.osgb) and a camera path for it.
//
//   dmmr-scenegen plant    [--seed S] [--triangles T] [--geodes G] -o OUT.osgb
//   dmmr-scenegen monument [--seed S] [--triangles T] [--geodes G] -o OUT.osgb
//   dmmr-scenegen replicate --copies N (--input FILE | --of plant|monument ...)
//                 [--spacing M] [--subdivide N] -o OUT.osgb
// Every command also takes --walkthrough PATH (default: OUT with extension
// .path), --frames N (default 120) and --path fly|orbit|around. plant and
// monument take --parts N: N scenes of unique geometry (seeds S..S+N-1, T/N
// triangles each) on a grid, written one at a time to OUT-000.EXT ... (a
// scene larger than memory, as many files; the walkthrough spans them all).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>

#include <unistd.h>

#include <CLI/CLI.hpp>
#include <osg/MatrixTransform>
#include <osgDB/FileNameUtils>
#include <osgDB/Registry>

#include "error.h"
#include "scenegen.h"
#include "walkthrough.h"

namespace sg = dmmr::scenegen;

namespace {

struct Options {
  std::string output, walkthrough, input, of, path;
  uint32_t frames = 120, copies = 0, parts = 0, subdivide = 1;
  double spacing = 0;
  uint64_t seed = 1, triangles = 1'000'000;
  uint32_t geodes = 0;
  bool geodesGiven = false;  // else each generator's own default
};

// CLI11 would wrap "-5" into a huge unsigned value; refuse signs up front.
const CLI::Validator kUnsigned(
    [](std::string& s) {
      return s.find('-') == std::string::npos ? std::string() : "must not be negative";
    },
    "UINT");

void addOutputOptions(CLI::App* cmd, Options& o) {
  cmd->add_option("-o,--output", o.output, "output scene, e.g. scene.osgb")->required();
  cmd->add_option("--walkthrough", o.walkthrough, "camera path to write (default: OUT.path)");
  // Upper bounds far above any scene this tool is for, so that a mistyped
  // count is an error, not hours of allocation.
  cmd->add_option("--frames", o.frames, "control points in the camera path (at most 10^6)")
      ->check(CLI::Range(1u, 1000000u))
      ->capture_default_str();
  cmd->add_option("--path", o.path,
                  "camera path kind (default: fly, orbit for one copy of a model; around: a "
                  "circle close around the scene's box, looking at its centre)")
      ->check(CLI::IsMember({"fly", "orbit", "around"}));
}

void addGeneratorOptions(CLI::App* cmd, Options& o) {
  cmd->add_option("--seed", o.seed, "random seed")->check(kUnsigned)->capture_default_str();
  cmd->add_option("--triangles", o.triangles, "target triangle count (at most 2*10^9)")
      ->check(kUnsigned)
      ->capture_default_str();
  cmd->add_option("--geodes", o.geodes,
                  "target geode count (default: 20000 plant, 1000 monument; at most 10^7)")
      ->check(CLI::Range(1u, 10000000u));
}

osg::ref_ptr<osg::Node> generate(const std::string& kind, const Options& o) {
  if (kind == "plant") {
    sg::PlantParams p{o.seed, o.triangles};
    if (o.geodesGiven) p.geodes = o.geodes;
    return sg::makePlant(p);
  }
  sg::MonumentParams p{o.seed, o.triangles};
  if (o.geodesGiven) p.geodes = o.geodes;
  return sg::makeMonument(p);
}

osg::ref_ptr<osg::Node> readInput(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec))
    throw dmmr::Error(
        dmmr::fileError(path, "cannot open input (no such file, or not a regular file)"));
  auto* reg = osgDB::Registry::instance();
  osgDB::ReaderWriter::ReadResult r = reg->readNode(path, reg->getOptions());
  if (!r.validNode()) {
    std::string why = r.message().empty() ? "" : " (" + r.message() + ")";
    throw dmmr::Error(dmmr::fileError(path, "cannot read input as a model" + why));
  }
  return r.getNode();
}

// Fails before any long generation when an output could not be created.
void checkOutput(const std::string& path, bool scene) {
  std::filesystem::path dir = std::filesystem::path(path).parent_path();
  std::error_code ec;
  if (!dir.empty() && !std::filesystem::is_directory(dir, ec))
    throw dmmr::Error(dmmr::fileError(path, "cannot write: no such folder " + dir.string()));
  if (!scene) return;
  std::string ext = osgDB::getLowerCaseFileExtension(path);
  if (ext.empty())
    throw dmmr::Error(dmmr::fileError(path, "output needs an extension OSG can write, e.g. .osgb"));
  if (!osgDB::Registry::instance()->getReaderWriterForExtension(ext))
    throw dmmr::Error(dmmr::fileError(path, "no OSG writer for ." + ext + " files"));
}

// Writes through a temporary file beside OUT (same extension, so the same OSG
// writer), then renames, so readers never see a partial scene.
void writeSceneAtomic(osg::Node& node, const std::string& out) {
  std::string tmp = out + ".tmp" + std::to_string(::getpid()) + "." + osgDB::getFileExtension(out);
  auto* reg = osgDB::Registry::instance();
  osgDB::ReaderWriter::WriteResult r = reg->writeNode(node, tmp, reg->getOptions());
  if (!r.success()) {
    std::remove(tmp.c_str());
    std::string why = r.message().empty() ? "" : " (" + r.message() + ")";
    throw dmmr::Error(dmmr::fileError(out, "cannot write scene" + why));
  }
  std::error_code ec;
  std::filesystem::rename(tmp, out, ec);
  if (ec) {
    std::remove(tmp.c_str());
    throw dmmr::Error(dmmr::fileError(out, "cannot write scene: " + ec.message()));
  }
}

std::string partName(const std::string& out, uint32_t i) {
  char n[16];
  std::snprintf(n, sizeof n, "-%03u.", i);
  return osgDB::getNameLessExtension(out) + n + osgDB::getFileExtension(out);
}

// --parts: each part is generated, placed, written and released before the
// next, so the generator holds one part at a time.
void writeParts(const std::string& command, const Options& o, osg::BoundingBox* bounds,
                sg::SceneStats* total) {
  uint32_t cols = uint32_t(std::ceil(std::sqrt(double(o.parts))));
  double spacing = 0;
  for (uint32_t i = 0; i < o.parts; ++i) {
    Options p = o;
    p.seed = o.seed + i;
    p.triangles = std::max<uint64_t>(1, o.triangles / o.parts);
    osg::ref_ptr<osg::Node> part = generate(command, p);
    osg::BoundingBox b = sg::sceneBounds(*part);
    if (i == 0) spacing = 1.1 * std::max(b.xMax() - b.xMin(), b.yMax() - b.yMin());
    double x = (double(i % cols) - (cols - 1) / 2.0) * spacing;
    double y = (double(i / cols) - (cols - 1) / 2.0) * spacing;
    osg::ref_ptr<osg::MatrixTransform> t =
        new osg::MatrixTransform(osg::Matrixd::translate(x, y, 0));
    t->addChild(part);
    writeSceneAtomic(*t, partName(o.output, i));
    bounds->expandBy(sg::sceneBounds(*t));
    sg::SceneStats s = sg::sceneStats(*t);
    total->geodes += s.geodes;
    total->geodeInstances += s.geodeInstances;
    total->geometries += s.geometries;
    total->triangles += s.triangles;
    total->instancedTriangles += s.instancedTriangles;
  }
}

void run(const std::string& command, Options& o) {
  auto start = std::chrono::steady_clock::now();
  if (o.frames == 0) throw dmmr::Error("--frames must be at least 1");
  if (o.triangles == 0) throw dmmr::Error("--triangles must be at least 1");
  if (o.geodesGiven && o.geodes == 0) throw dmmr::Error("--geodes must be at least 1");
  if (o.walkthrough.empty()) o.walkthrough = osgDB::getNameLessExtension(o.output) + ".path";
  checkOutput(o.output, true);
  checkOutput(o.walkthrough, false);
  bool orbit = false;
  osg::ref_ptr<osg::Node> scene;
  if (o.parts > 0) {
    if (command == "replicate") throw dmmr::Error("--parts is for plant and monument");
    osg::BoundingBox bounds;
    sg::SceneStats s;
    writeParts(command, o, &bounds, &s);
    dmmr::writeWalkthrough(
        o.walkthrough,
        sg::makeWalkthrough(bounds, o.frames,
                            o.path == "orbit" ? sg::PathKind::Orbit : sg::PathKind::FlyThrough));
    double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    std::printf(
        "%s ... %s: %u parts, %llu geodes, %llu unique geometries, %llu triangles; walkthrough "
        "%s (%u frames); %.1f s\n",
        partName(o.output, 0).c_str(), partName(o.output, o.parts - 1).c_str(), o.parts,
        (unsigned long long)s.geodeInstances, (unsigned long long)s.geometries,
        (unsigned long long)s.triangles, o.walkthrough.c_str(), o.frames, secs);
    return;
  }
  if (command == "replicate") {
    if (o.copies == 0) throw dmmr::Error("--copies must be at least 1");
    if (o.input.empty() == o.of.empty())
      throw dmmr::Error("replicate needs exactly one of --input FILE or --of plant|monument");
    osg::ref_ptr<osg::Node> input = o.of.empty() ? readInput(o.input) : generate(o.of, o);
    try {
      input = sg::subdivide(input.get(), o.subdivide);
      scene = sg::replicate(input.get(), o.copies, o.spacing);
    } catch (const dmmr::Error& e) {
      throw dmmr::Error(o.input.empty() ? e.what() : dmmr::fileError(o.input, e.what()));
    }
    orbit = o.of.empty() && o.copies == 1;
  } else {
    scene = generate(command, o);
  }
  sg::PathKind kind = orbit ? sg::PathKind::Orbit : sg::PathKind::FlyThrough;
  if (o.path == "orbit") kind = sg::PathKind::Orbit;
  if (o.path == "fly") kind = sg::PathKind::FlyThrough;
  if (o.path == "around") kind = sg::PathKind::Around;

  dmmr::Walkthrough w = sg::makeWalkthrough(sg::sceneBounds(*scene), o.frames, kind);
  writeSceneAtomic(*scene, o.output);
  dmmr::writeWalkthrough(o.walkthrough, w);

  sg::SceneStats s = sg::sceneStats(*scene);
  double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::printf(
      "%s: %llu geodes (%llu unique), %llu unique geometries, %llu triangles, %llu instanced "
      "triangles; walkthrough %s (%u frames); %.1f s\n",
      o.output.c_str(), (unsigned long long)s.geodeInstances, (unsigned long long)s.geodes,
      (unsigned long long)s.geometries, (unsigned long long)s.triangles,
      (unsigned long long)s.instancedTriangles, o.walkthrough.c_str(), o.frames, secs);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Generates dmmr test scenes and camera paths through them."};
  app.require_subcommand(1, 1);
  Options o;
  CLI::App* plant = app.add_subcommand("plant", "an industrial plant, about 100 x 100 x 40 m");
  CLI::App* monument = app.add_subcommand("monument", "a monument site, about 400 x 400 m");
  CLI::App* rep = app.add_subcommand("replicate", "copies of a model on a grid, instanced");
  for (CLI::App* cmd : {plant, monument, rep}) {
    addOutputOptions(cmd, o);
    addGeneratorOptions(cmd, o);
  }
  rep->add_option("--copies", o.copies, "number of copies (at most 10^6)")
      ->required()
      ->check(CLI::Range(1u, 1000000u));
  for (CLI::App* cmd : {plant, monument})
    cmd->add_option("--parts", o.parts,
                    "write N files of unique geometry, OUT-000.EXT ..., one at a time (1 to 10^5)")
        ->check(CLI::Range(1u, 100000u));
  rep->add_option("--spacing", o.spacing, "grid spacing in metres (<= 0: automatic)");
  rep->add_option("--input", o.input, "model to replicate (any format OSG reads)");
  rep->add_option("--subdivide", o.subdivide,
                  "cut every triangle of the input into N*N (one dense mesh of a scanned model)")
      ->check(CLI::Range(1u, 1000u))
      ->capture_default_str();
  rep->add_option("--of", o.of, "replicate a freshly generated scene instead")
      ->check(CLI::IsMember({"plant", "monument"}));
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    std::fprintf(stderr, "dmmr-scenegen: %s\n", e.what());
    return 1;
  }
  try {
    CLI::App* cmd = app.get_subcommands().front();
    o.geodesGiven = cmd->count("--geodes") > 0;
    run(cmd->get_name(), o);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "dmmr-scenegen: %s\n", e.what());
    return 1;
  }
  return 0;
}
