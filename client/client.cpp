#include "client.h"

#include <chrono>
#include <memory>

#include "draw.h"
#include "error.h"
#include "mesh_provider.h"
#include "protocol.h"
#include "scene.h"

namespace dmmr {

namespace {

using Clock = std::chrono::steady_clock;
double msSince(Clock::time_point t) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t).count();
}

// Everything a client holds between jobs.
struct ClientState {
  Scene scene;
  std::unique_ptr<GlContext> context;
  std::unique_ptr<Renderer> renderer;
  std::unique_ptr<KeepAllMeshProvider> meshes;
};

SubFrame renderJob(ClientState& s, const FrameJob& job, Codec codec) {
  SubFrame out;
  out.frame = job.frame;
  out.region = job.region;
  ClientStats& st = out.stats;
  auto t0 = Clock::now();
  s.renderer->beginFrame(job.camera, job.region);
  for (uint32_t index : job.objects) {  // ascending, as the reference draws
    if (index >= s.scene.objects.size())
      throw Error("job names object " + std::to_string(index) + " beyond the scene");
    const ObjectBounds& o = s.scene.objects[index];
    auto tl = Clock::now();
    const GpuMesh& mesh = s.meshes->acquire(o.geometry);
    st.load_ms += msSince(tl);
    s.renderer->draw(mesh, o.transform, s.meshes->textures());
    ++st.objects;
    st.triangles += mesh.triangles;
  }
  s.renderer->finish();
  st.render_ms = msSince(t0) - st.load_ms;
  auto tr = Clock::now();
  std::vector<uint8_t> rgba, rgb;
  s.renderer->readPixels(job.region, &rgba);
  rgb.resize(size_t(job.region.area()) * 3);
  for (size_t i = 0, n = size_t(job.region.area()); i < n; ++i)
    for (int c = 0; c < 3; ++c) rgb[i * 3 + c] = rgba[i * 4 + c];
  st.readback_ms = msSince(tr);
  auto tc = Clock::now();
  out.codec = codec;
  out.raw_size = rgb.size();
  out.data = compress(codec, rgb.data(), rgb.size());
  st.compress_ms = msSince(tc);
  st.bytes_raw = rgb.size();
  st.bytes_sent = out.data.size();
  return out;
}

}  // namespace

int runClient(Comm& comm, const ClientOptions& opts) {
  int ok = 0;
  comm.broadcast(0, &ok);  // did the server load the scene?
  if (!ok) return 1;

  ClientState s;
  std::string problem;
  try {
    s.scene = loadScene(opts.scene, /*with_skeleton=*/false);
    s.context = createContext(opts.context);
    s.renderer = std::make_unique<Renderer>(s.context->gl(), opts.view.width, opts.view.height);
    s.meshes = std::make_unique<KeepAllMeshProvider>(s.scene, *s.renderer);
  } catch (const std::exception& e) {
    problem = e.what();
  }
  comm.send(0, Tag::Hello, encodeText(problem));
  int go = 0;
  comm.broadcast(0, &go);
  if (!go) return 1;

  int status = 0;
  bool failed = false;
  for (;;) {
    Message m = comm.recv(0);
    if (m.tag == Tag::Shutdown) break;
    if (m.tag != Tag::Job || failed) continue;  // after a failure, wait for Shutdown
    try {
      SubFrame sf = renderJob(s, decodeJob(m.bytes), opts.codec);
      comm.send(0, Tag::SubFrame, encodeSubFrame(sf));
    } catch (const std::exception& e) {
      comm.send(0, Tag::Error, encodeText(e.what()));
      failed = true;
      status = 1;
    }
  }
  comm.send(0, Tag::Bye, {});
  return status;
}

}  // namespace dmmr
