// dmmr-plan --scene DIR --walkthrough PATH --clients N [...]: runs only the
// server's per-frame planning (culling, footprints, division) for every frame,
// without MPI or rendering, and writes one CSV row per frame and client
// count: the server's algorithm measured on its own.
#include <CLI/CLI.hpp>

#include <algorithm>
#include <cstdio>
#include "cli_options.h"

#include "atomic_file.h"
#include "error.h"
#include "plan.h"
#include "walkthrough.h"

int main(int argc, char** argv) {
  std::string sceneDir, pathFile, csvFile;
  std::vector<int> clientCounts = {2};
  dmmr::ViewOptions v;
  int repeats = 5;
  CLI::App app{"dmmr-plan: time the server's culling and division over a walkthrough"};
  app.add_option("--scene", sceneDir, "preprocessed scene directory")->required();
  app.add_option("--walkthrough", pathFile, "AnimationPath file")->required();
  app.add_option("--clients", clientCounts, "client counts to plan for")
      ->check(CLI::Range(1, 4096));
  app.add_option("--width", v.width, "image width")->check(CLI::Range(1, 16384));
  app.add_option("--height", v.height, "image height")->check(CLI::Range(1, 16384));
  app.add_option("--fovy", v.fovy_deg, "vertical field of view, degrees")
      ->check(dmmr::finiteRange(1.0, 179.0));
  app.add_option("--repeats", repeats, "plans per frame; the median time is kept")
      ->check(CLI::Range(1, 1000));
  app.add_option("--csv", csvFile, "output CSV (default: stdout)");
  CLI11_PARSE(app, argc, argv);
  try {
    dmmr::Scene scene = dmmr::loadScene(sceneDir);
    dmmr::Walkthrough path = dmmr::readWalkthrough(pathFile);
    double near = v.near > 0 ? v.near : dmmr::defaultNear(scene);
    dmmr::FramePlanner planner(scene);
    std::string csv =
        "frame,clients,objects_in_frustum,triangles_in_frustum,cull_ms,divide_ms,project_ms,"
        "max_region_triangles,mean_region_triangles\n";
    for (int clients : clientCounts)
      for (size_t f = 0; f < path.points.size(); ++f) {
        dmmr::Camera cam = dmmr::cameraAt(path.points[f], v.width, v.height, v.fovy_deg, near);
        std::vector<double> cull, divide, project;
        dmmr::FramePlan plan;
        for (int r = 0; r < repeats; ++r) {
          plan = planner.plan(cam, v.width, v.height, clients);
          cull.push_back(plan.cull_ms);
          divide.push_back(plan.divide_ms);
          project.push_back(plan.project_ms);
        }
        std::nth_element(cull.begin(), cull.begin() + repeats / 2, cull.end());
        std::nth_element(divide.begin(), divide.begin() + repeats / 2, divide.end());
        std::nth_element(project.begin(), project.begin() + repeats / 2, project.end());
        double maxW = 0, sumW = 0;
        for (const auto& reg : plan.regions) {
          maxW = std::max(maxW, double(reg.weight));
          sumW += double(reg.weight);
        }
        char row[256];
        std::snprintf(row, sizeof row, "%zu,%d,%llu,%llu,%.4f,%.4f,%.4f,%.0f,%.1f\n", f, clients,
                      (unsigned long long)plan.objects_in_frustum,
                      (unsigned long long)plan.triangles_in_frustum, cull[size_t(repeats / 2)],
                      divide[size_t(repeats / 2)], project[size_t(repeats / 2)], maxW,
                      sumW / clients);
        csv += row;
      }
    if (csvFile.empty())
      std::fputs(csv.c_str(), stdout);
    else
      dmmr::writeFileAtomic(csvFile, csv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "dmmr-plan: %s\n", e.what());
    return 1;
  }
  return 0;
}
