#include "raytrace.h"

#include <embree3/rtcore.h>
#include <pmmintrin.h>
#include <xmmintrin.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstring>
#include <functional>
#include <limits>
#include <mutex>
#include <string>
#include <thread>
#include <unordered_map>

#include "affinity.h"
#include "error.h"

namespace dmmr {

namespace {

// ---- small float vectors (shading runs in float, as the GL shader does) ----
struct V3 {
  float x = 0, y = 0, z = 0;
};
inline V3 operator+(V3 a, V3 b) {
  return {a.x + b.x, a.y + b.y, a.z + b.z};
}
inline V3 operator-(V3 a, V3 b) {
  return {a.x - b.x, a.y - b.y, a.z - b.z};
}
inline V3 operator-(V3 a) {
  return {-a.x, -a.y, -a.z};
}
inline V3 operator*(V3 a, float s) {
  return {a.x * s, a.y * s, a.z * s};
}
inline V3 operator*(V3 a, V3 b) {
  return {a.x * b.x, a.y * b.y, a.z * b.z};
}
inline float dot(V3 a, V3 b) {
  return a.x * b.x + a.y * b.y + a.z * b.z;
}
inline V3 cross(V3 a, V3 b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
inline float length(V3 a) {
  return std::sqrt(dot(a, a));
}

struct V4 {
  float r = 0, g = 0, b = 0, a = 0;
};
inline V4 operator*(V4 p, V4 q) {
  return {p.r * q.r, p.g * q.g, p.b * q.b, p.a * q.a};
}

// GL's float to UNORM8 conversion: clamp, scale, round to nearest.
inline uint8_t unorm8(float v) {
  v = std::min(std::max(v, 0.f), 1.f);
  return uint8_t(v * 255.f + 0.5f);
}

RTCBuildQuality embreeQuality(BvhQuality q) {
  switch (q) {
    case BvhQuality::Low:
      return RTC_BUILD_QUALITY_LOW;
    case BvhQuality::High:
      return RTC_BUILD_QUALITY_HIGH;
    case BvhQuality::Medium:
      break;
  }
  return RTC_BUILD_QUALITY_MEDIUM;
}

const char* embreeErrorName(RTCError e) {
  switch (e) {
    case RTC_ERROR_NONE:
      return "no error";
    case RTC_ERROR_UNKNOWN:
      return "unknown error";
    case RTC_ERROR_INVALID_ARGUMENT:
      return "invalid argument";
    case RTC_ERROR_INVALID_OPERATION:
      return "invalid operation";
    case RTC_ERROR_OUT_OF_MEMORY:
      return "out of memory";
    case RTC_ERROR_UNSUPPORTED_CPU:
      return "unsupported CPU";
    case RTC_ERROR_CANCELLED:
      return "cancelled";
  }
  return "error";
}

// Denormals flushed to zero on every thread that traces (Embree's advice:
// denormal arithmetic in traversal is very slow). Restores the caller's mode.
class FlushDenormals {
 public:
  FlushDenormals() : saved_(_mm_getcsr()) {
    _MM_SET_FLUSH_ZERO_MODE(_MM_FLUSH_ZERO_ON);
    _MM_SET_DENORMALS_ZERO_MODE(_MM_DENORMALS_ZERO_ON);
  }
  ~FlushDenormals() { _mm_setcsr(saved_); }
  FlushDenormals(const FlushDenormals&) = delete;
  FlushDenormals& operator=(const FlushDenormals&) = delete;

 private:
  unsigned saved_;
};

}  // namespace

namespace {
struct TopLevel;
class EmbreeMesh;
// Points every slot of `top` that holds `mesh` at the empty scene (the mesh
// is going away). The device's mutex held.
void unbindMesh(TopLevel& top, const EmbreeMesh* mesh);
}  // namespace

// ---- the device, shared by the tracer and every mesh it built ---------------
// Every Embree call that allocates or frees (scene builds and releases) holds
// `mutex`, so that the memory monitor's running total, read before and after
// a mesh's build, counts that mesh's memory alone. Tracing allocates nothing
// and runs without it.
struct EmbreeDevice {
  RTCDevice device = nullptr;
  std::mutex mutex;
  std::atomic<int64_t> allocated{0};  // net bytes Embree holds (memory monitor)
  std::mutex error_mutex;
  std::string error;  // the last error Embree reported (its callback)
  // The tracer's top level (its Impl owns it; null once the tracer is gone),
  // so that a mesh released while bound there is unbound first.
  TopLevel* top = nullptr;

  explicit EmbreeDevice(int threads) {
    std::string config = "threads=" + std::to_string(threads);
    device = rtcNewDevice(config.c_str());
    if (!device)
      throw Error(std::string("Embree: cannot create a device: ") +
                  embreeErrorName(rtcGetDeviceError(nullptr)));
    rtcSetDeviceErrorFunction(device, &EmbreeDevice::onError, this);
    rtcSetDeviceMemoryMonitorFunction(device, &EmbreeDevice::onMemory, this);
  }
  ~EmbreeDevice() { rtcReleaseDevice(device); }
  EmbreeDevice(const EmbreeDevice&) = delete;
  EmbreeDevice& operator=(const EmbreeDevice&) = delete;

  static void onError(void* self, RTCError code, const char* str) {
    auto* d = static_cast<EmbreeDevice*>(self);
    std::lock_guard<std::mutex> lock(d->error_mutex);
    d->error = std::string(embreeErrorName(code)) + (str ? std::string(": ") + str : "");
  }
  // Allocations come with positive bytes (before they happen: post false),
  // frees and failed allocations' undo with negative ones. Called from any
  // of Embree's build threads.
  static bool onMemory(void* self, ssize_t bytes, bool /*post*/) {
    static_cast<EmbreeDevice*>(self)->allocated.fetch_add(int64_t(bytes),
                                                          std::memory_order_relaxed);
    return true;
  }
  // Throws Error when Embree reported one since the last call (`what`: the
  // operation, for the message).
  void check(const std::string& what) {
    RTCError e = rtcGetDeviceError(device);
    std::string msg;
    {
      std::lock_guard<std::mutex> lock(error_mutex);
      msg.swap(error);
    }
    if (e == RTC_ERROR_NONE && msg.empty()) return;
    throw Error("Embree: " + what + " failed: " + (msg.empty() ? embreeErrorName(e) : msg));
  }
};

namespace {

class EmbreeMesh final : public RtMesh {
 public:
  explicit EmbreeMesh(std::shared_ptr<EmbreeDevice> d) : dev(std::move(d)) {}
  ~EmbreeMesh() override {
    std::lock_guard<std::mutex> lock(dev->mutex);
    if (dev->top) unbindMesh(*dev->top, this);
    if (scene) rtcReleaseScene(scene);
  }
  uint64_t bytes() const override { return bvh_bytes + copy_bytes; }
  uint64_t bvhBytes() const override { return bvh_bytes; }
  uint64_t triangles() const override { return indices.size() / 3; }

  std::shared_ptr<EmbreeDevice> dev;
  RTCScene scene = nullptr;
  // What shading needs, per vertex (normals, colours, texture coordinates
  // empty when the geometry has none or, for coordinates, no submesh is
  // textured); positions carry one float of padding (Embree reads vertices
  // with 16-byte loads).
  std::vector<float> positions, normals, texcoords;
  std::vector<uint8_t> colors;
  // The triangles of the submeshes, in submesh order (what the raster path
  // draws); triangle t belongs to the first submesh with t < submesh_end.
  std::vector<uint32_t> indices;
  std::vector<SubMesh> submeshes;
  std::vector<uint32_t> submesh_end;
  uint64_t bvh_bytes = 0, copy_bytes = 0;
  // The top-level slots that instance this mesh now (TopSlot::pos is each
  // one's index here); changed under the device's mutex.
  mutable std::vector<uint32_t> slots;

  const SubMesh& submeshOf(uint32_t tri) const {
    size_t k =
        size_t(std::upper_bound(submesh_end.begin(), submesh_end.end(), tri) - submesh_end.begin());
    return submeshes[std::min(k, submeshes.size() - 1)];
  }
};

// One object of the frame: its mesh, its transform's normal matrix (world
// space, column-major 3x3, as the raster path's u_nrm) and effect.
struct FrameInstance {
  const EmbreeMesh* mesh = nullptr;
  float nrm[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  SurfaceEffect effect = SurfaceEffect::None;
};

struct Hit {
  bool hit = false;
  float t = 0;
  float u = 0, v = 0;
  unsigned prim = 0, inst = 0;
};

// One instance geometry of the top level: it holds one object (its key)
// while `used`, bound to that object's mesh, or to the empty scene and
// disabled.
struct TopSlot {
  RTCGeometry geom = nullptr;
  uint32_t key = 0;
  bool used = false, enabled = false;
  const EmbreeMesh* mesh = nullptr;  // null: the empty scene
  uint32_t pos = 0;                  // index in mesh->slots
  Mat4d object_to_world;             // as set, against anchor generation `anchor_gen`
  uint64_t anchor_gen = 0, stamp = 0;
};

// The top level, kept from call to call so that a frame whose objects are
// those of the last one costs no Embree call at all (docs/raytrace.md).
// Transforms are in world space less `anchor`, a grid point near the eye
// (anchorFor), so that positions keep float precision near the camera.
struct TopLevel {
  RTCScene scene = nullptr, empty = nullptr;
  std::vector<TopSlot> slots;       // slot s is instance geometry s
  std::vector<FrameInstance> info;  // by slot, for shading
  // key -> slot (kNoSlot: none): a vector for the keys objects have (dense,
  // below kDenseKeys), a map beyond.
  static constexpr uint32_t kNoSlot = UINT32_MAX, kDenseKeys = 1u << 24;
  std::vector<uint32_t> dense_slot;
  std::unordered_map<uint32_t, uint32_t> sparse_slot;
  std::vector<uint32_t> free;   // unused slots
  std::vector<uint32_t> order;  // slot of each instance of the last call
  Vec3d anchor;
  bool anchored = false;
  uint64_t anchor_gen = 0, stamp = 0;
  uint64_t list_version = 0;  // the caller's version of the list it holds (0: none)
  bool dirty = false;         // changed since the last commit

  uint32_t slotOf(uint32_t key) const {
    if (key < kDenseKeys) return key < dense_slot.size() ? dense_slot[key] : kNoSlot;
    auto it = sparse_slot.find(key);
    return it == sparse_slot.end() ? kNoSlot : it->second;
  }
  void setSlotOf(uint32_t key, uint32_t s) {
    if (key >= kDenseKeys) {
      if (s == kNoSlot)
        sparse_slot.erase(key);
      else
        sparse_slot[key] = s;
      return;
    }
    if (key >= dense_slot.size()) dense_slot.resize(size_t(key) + 1, kNoSlot);
    dense_slot[key] = s;
  }

  // Binds slot `s` to `mesh` (null: the empty scene, disabled).
  void bind(uint32_t s, const EmbreeMesh* mesh) {
    TopSlot& t = slots[s];
    if (t.mesh) {  // off the old mesh's list
      std::vector<uint32_t>& list = t.mesh->slots;
      list[t.pos] = list.back();
      slots[list[t.pos]].pos = t.pos;
      list.pop_back();
    }
    t.mesh = mesh;
    info[s].mesh = mesh;
    if (mesh) {
      t.pos = uint32_t(mesh->slots.size());
      mesh->slots.push_back(s);
    }
    rtcSetGeometryInstancedScene(t.geom, mesh ? mesh->scene : empty);
    if (bool on = mesh != nullptr; on != t.enabled) {
      if (on)
        rtcEnableGeometry(t.geom);
      else
        rtcDisableGeometry(t.geom);
      t.enabled = on;
    }
    rtcCommitGeometry(t.geom);
    dirty = true;
  }
};

void unbindMesh(TopLevel& top, const EmbreeMesh* mesh) {
  while (!mesh->slots.empty()) top.bind(mesh->slots.back(), nullptr);
}

}  // namespace

// ---- a fixed pool of threads for tiles ---------------------------------------
class TilePool {
 public:
  explicit TilePool(int threads) {
    for (int i = 1; i < threads; ++i) workers_.emplace_back([this] { loop(); });
  }
  ~TilePool() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stop_ = true;
    }
    wake_.notify_all();
    for (std::thread& t : workers_) t.join();
  }
  // Runs fn(i) for every i in [0, count) over the workers and the calling
  // thread; returns when all are done. The first exception is rethrown.
  void run(int count, const std::function<void(int)>& fn) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      fn_ = &fn;
      count_ = count;
      next_.store(0);
      busy_ = int(workers_.size());
      error_ = nullptr;
      ++generation_;
    }
    wake_.notify_all();
    work();
    std::unique_lock<std::mutex> lock(mutex_);
    done_.wait(lock, [this] { return busy_ == 0; });
    fn_ = nullptr;
    if (error_) std::rethrow_exception(error_);
  }

 private:
  void loop() {
    FlushDenormals ftz;
    uint64_t seen = 0;
    for (;;) {
      {
        std::unique_lock<std::mutex> lock(mutex_);
        wake_.wait(lock, [&] { return stop_ || generation_ != seen; });
        if (stop_) return;
        seen = generation_;
      }
      work();
      std::lock_guard<std::mutex> lock(mutex_);
      if (--busy_ == 0) done_.notify_all();
    }
  }
  void work() {
    for (;;) {
      int i = next_.fetch_add(1);
      if (i >= count_) return;
      try {
        (*fn_)(i);
      } catch (...) {
        std::lock_guard<std::mutex> lock(error_mutex_);
        if (!error_) error_ = std::current_exception();
        next_.store(count_);
      }
    }
  }

  std::vector<std::thread> workers_;
  std::mutex mutex_, error_mutex_;
  std::condition_variable wake_, done_;
  const std::function<void(int)>* fn_ = nullptr;
  int count_ = 0, busy_ = 0;
  std::atomic<int> next_{0};
  uint64_t generation_ = 0;
  bool stop_ = false;
  std::exception_ptr error_;
};

struct RayTracer::Impl {
  int threads = 1;
  std::shared_ptr<EmbreeDevice> dev;
  std::unique_ptr<TilePool> pool;
  std::mutex render_mutex;  // one frame at a time (the pool and the top level)
  TopLevel top;

  ~Impl() {
    if (!dev) return;
    std::lock_guard<std::mutex> lock(dev->mutex);
    dev->top = nullptr;  // meshes that outlive the tracer have nothing to unbind
    for (TopSlot& t : top.slots) {
      if (t.mesh) t.mesh->slots.clear();
      rtcReleaseGeometry(t.geom);
    }
    if (top.scene) rtcReleaseScene(top.scene);  // and the slots attached to it
    if (top.empty) rtcReleaseScene(top.empty);
  }
};

RayTracer::RayTracer(int threads) : impl_(std::make_unique<Impl>()) {
  impl_->threads = threads > 0 ? threads : allowedCpuCount();
  impl_->dev = std::make_shared<EmbreeDevice>(impl_->threads);
  impl_->pool = std::make_unique<TilePool>(impl_->threads);
  std::lock_guard<std::mutex> lock(impl_->dev->mutex);
  TopLevel& top = impl_->top;
  top.empty = rtcNewScene(impl_->dev->device);
  rtcCommitScene(top.empty);
  top.scene = rtcNewScene(impl_->dev->device);
  rtcCommitScene(top.scene);  // empty, ready for a frame without objects
  impl_->dev->check("creating the top level");
  impl_->dev->top = &top;
}

RayTracer::~RayTracer() = default;

std::unique_ptr<RtMesh> RayTracer::build(const GeometryData& g, BvhQuality quality, bool compact) {
  const size_t nv = g.vertexCount();
  if (g.positions.size() % 3 != 0 || (!g.normals.empty() && g.normals.size() != nv * 3) ||
      (!g.colors.empty() && g.colors.size() != nv * 4) ||
      (!g.texcoords.empty() && g.texcoords.size() != nv * 2))
    throw Error("ray tracer: geometry attributes do not match its " + std::to_string(nv) +
                " vertices");
  if (nv >= (uint64_t(1) << 32)) throw Error("ray tracer: too many vertices");
  auto m = std::make_unique<EmbreeMesh>(impl_->dev);
  bool textured = false;
  uint64_t total = 0;
  for (const SubMesh& s : g.submeshes) {
    if (s.index_count % 3 != 0 || uint64_t(s.first_index) + s.index_count > g.indices.size())
      throw Error("ray tracer: a submesh's index range lies outside the geometry's indices");
    total += s.index_count;
  }
  if (total / 3 >= RTC_INVALID_GEOMETRY_ID) throw Error("ray tracer: too many triangles");
  // One spare index of capacity: Embree may read the last triangle's three
  // indices with a 16-byte load, as it does vertices.
  m->indices.reserve(size_t(total) + 1);
  for (const SubMesh& s : g.submeshes) {
    m->indices.insert(m->indices.end(), g.indices.begin() + s.first_index,
                      g.indices.begin() + s.first_index + s.index_count);
    m->submesh_end.push_back(uint32_t(m->indices.size() / 3));
    m->submeshes.push_back(s);
    textured |= s.texture >= 0;
  }
  for (uint32_t i : m->indices)
    if (i >= nv) throw Error("ray tracer: an index refers to a vertex that does not exist");
  m->positions.reserve(g.positions.size() + 1);
  m->positions = g.positions;
  m->positions.push_back(0.f);  // padding for Embree's 16-byte vertex loads
  m->normals = g.normals;
  m->colors = g.colors;
  if (textured) m->texcoords = g.texcoords;
  m->copy_bytes = (m->positions.size() + m->normals.size() + m->texcoords.size()) * 4 +
                  m->colors.size() + m->indices.capacity() * 4 +
                  m->submeshes.size() * (sizeof(SubMesh) + 4);

  const size_t ntri = m->indices.size() / 3;
  EmbreeDevice& d = *impl_->dev;
  std::lock_guard<std::mutex> lock(d.mutex);
  d.check("an earlier call");
  const int64_t before = d.allocated.load();
  m->scene = rtcNewScene(d.device);
  rtcSetSceneFlags(m->scene, compact ? RTC_SCENE_FLAG_COMPACT : RTC_SCENE_FLAG_NONE);
  rtcSetSceneBuildQuality(m->scene, embreeQuality(quality));
  if (ntri > 0) {
    RTCGeometry geom = rtcNewGeometry(d.device, RTC_GEOMETRY_TYPE_TRIANGLE);
    rtcSetGeometryBuildQuality(geom, embreeQuality(quality));
    rtcSetSharedGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                               m->positions.data(), 0, 3 * sizeof(float), nv);
    rtcSetSharedGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, m->indices.data(),
                               0, 3 * sizeof(uint32_t), ntri);
    rtcCommitGeometry(geom);
    rtcAttachGeometryByID(m->scene, geom, 0);
    rtcReleaseGeometry(geom);
  }
  rtcCommitScene(m->scene);
  d.check("building a BVH of " + std::to_string(ntri) + " triangles");
  m->bvh_bytes = uint64_t(std::max<int64_t>(d.allocated.load() - before, 0));
  return m;
}

namespace {

// Everything one frame's rays need, read-only while tracing.
struct Frame {
  RTCScene scene = nullptr;
  const FrameInstance* instances = nullptr;  // by instance ID (top-level slot)
  const std::vector<const TextureData*>* textures = nullptr;
  RayOptions opts;
  V3 light;  // world space, unit
  V3 background;
};

// Bilinear sample of `t`'s full-resolution image at (s, t), GL's rules:
// texel centres at (i + 0.5) / size, repeat or clamp-to-edge wrapping.
V4 sampleBilinear(const TextureData& tex, float s, float t) {
  if (tex.width == 0 || tex.height == 0 || tex.rgba.size() < size_t(tex.width) * tex.height * 4)
    return {0, 0, 0, 1};
  const int w = int(tex.width), h = int(tex.height);
  float x = s * float(w) - 0.5f, y = t * float(h) - 0.5f;
  float fx = std::floor(x), fy = std::floor(y);
  float ax = x - fx, ay = y - fy;
  auto wrap = [](long long i, int n, bool repeat) {
    if (repeat) {
      long long r = i % n;
      return int(r < 0 ? r + n : r);
    }
    return int(std::min<long long>(std::max<long long>(i, 0), n - 1));
  };
  // Coordinates far outside [0, 1] (repeat) stay exact in 64-bit integers.
  long long ix = (long long)std::max(std::min(fx, 4e18f), -4e18f);
  long long iy = (long long)std::max(std::min(fy, 4e18f), -4e18f);
  int x0 = wrap(ix, w, tex.repeat_s), x1 = wrap(ix + 1, w, tex.repeat_s);
  int y0 = wrap(iy, h, tex.repeat_t), y1 = wrap(iy + 1, h, tex.repeat_t);
  auto texel = [&](int px, int py) {
    const uint8_t* p = &tex.rgba[(size_t(py) * size_t(w) + size_t(px)) * 4];
    return V4{p[0] / 255.f, p[1] / 255.f, p[2] / 255.f, p[3] / 255.f};
  };
  V4 a = texel(x0, y0), b = texel(x1, y0), c = texel(x0, y1), e = texel(x1, y1);
  auto lerp = [](V4 p, V4 q, float f) {
    return V4{p.r + (q.r - p.r) * f, p.g + (q.g - p.g) * f, p.b + (q.b - p.b) * f,
              p.a + (q.a - p.a) * f};
  };
  return lerp(lerp(a, b, ax), lerp(c, e, ax), ay);
}

class Tracer {
 public:
  explicit Tracer(const Frame& f) : f_(f) {}

  // The colour seen along `dir` from `org` (anchor space), `depth` bounces in.
  V3 trace(V3 org, V3 dir, float tnear, int depth) {
    Hit h = intersect(org, dir, tnear, false);
    return h.hit ? shade(h, org, dir, depth) : f_.background;
  }

  Hit intersect(V3 org, V3 dir, float tnear, bool coherent) {
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    ctx.flags =
        coherent ? RTC_INTERSECT_CONTEXT_FLAG_COHERENT : RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT;
    RTCRayHit rh;
    rh.ray.org_x = org.x;
    rh.ray.org_y = org.y;
    rh.ray.org_z = org.z;
    rh.ray.dir_x = dir.x;
    rh.ray.dir_y = dir.y;
    rh.ray.dir_z = dir.z;
    rh.ray.tnear = tnear;
    rh.ray.tfar = std::numeric_limits<float>::infinity();
    rh.ray.time = 0;
    rh.ray.mask = 0xFFFFFFFFu;
    rh.ray.id = 0;
    rh.ray.flags = 0;
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(f_.scene, &ctx, &rh);
    Hit h;
    if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return h;
    h.hit = true;
    h.t = rh.ray.tfar;
    h.u = rh.hit.u;
    h.v = rh.hit.v;
    h.prim = rh.hit.primID;
    h.inst = rh.hit.instID[0];
    return h;
  }

  bool occluded(V3 org, V3 dir) {
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    ctx.flags = RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT;
    RTCRay r;
    r.org_x = org.x;
    r.org_y = org.y;
    r.org_z = org.z;
    r.dir_x = dir.x;
    r.dir_y = dir.y;
    r.dir_z = dir.z;
    r.tnear = 0;
    r.tfar = std::numeric_limits<float>::infinity();
    r.time = 0;
    r.mask = 0xFFFFFFFFu;
    r.id = 0;
    r.flags = 0;
    rtcOccluded1(f_.scene, &ctx, &r);
    return r.tfar < 0;  // Embree sets tfar to -inf on a hit
  }

  // What lighting needs of hit `h` on the ray org + t dir (anchor space): the
  // raster shader's base colour and normal, and where secondary rays start.
  struct Surface {
    V3 base;        // diffuse * vertex colour * texture, RGB
    V3 v;           // towards the ray's origin, unit
    V3 nf;          // unit normal faced towards v
    float nv = 0;   // dot(n, v) before facing: > 0 where the ray meets the front
    V3 p;           // the hit point
    float eps = 0;  // offset out of the surface for secondary rays
    SurfaceEffect effect = SurfaceEffect::None;
  };

  Surface surface(const Hit& h, V3 org, V3 dir) const {
    const FrameInstance& in = f_.instances[h.inst];
    const EmbreeMesh& m = *in.mesh;
    const uint32_t* tri = &m.indices[size_t(h.prim) * 3];
    const float w0 = 1.f - h.u - h.v, w1 = h.u, w2 = h.v;
    auto interp3 = [&](const std::vector<float>& a) {
      const float *p = &a[size_t(tri[0]) * 3], *q = &a[size_t(tri[1]) * 3],
                  *r = &a[size_t(tri[2]) * 3];
      return V3{w0 * p[0] + w1 * q[0] + w2 * r[0], w0 * p[1] + w1 * q[1] + w2 * r[1],
                w0 * p[2] + w1 * q[2] + w2 * r[2]};
    };
    auto normalMatrix = [&](V3 n) {
      const float* k = in.nrm;
      return V3{k[0] * n.x + k[3] * n.y + k[6] * n.z, k[1] * n.x + k[4] * n.y + k[7] * n.z,
                k[2] * n.x + k[5] * n.y + k[8] * n.z};
    };
    // The normal: the interpolated vertex normal through the normal matrix,
    // or the facet normal where that is (near) zero, as the raster shader.
    V3 n;
    if (!m.normals.empty()) n = normalMatrix(interp3(m.normals));
    if (dot(n, n) <= 1e-12f) {
      auto vertex = [&](int k) {
        const float* p = &m.positions[size_t(tri[k]) * 3];
        return V3{p[0], p[1], p[2]};
      };
      V3 a = vertex(0);
      n = normalMatrix(cross(vertex(1) - a, vertex(2) - a));
    }
    float ln = length(n);
    n = ln > 0 ? n * (1.f / ln) : V3{0, 0, 1};
    Surface s;
    s.v = -dir * (1.f / length(dir));

    const SubMesh& sm = m.submeshOf(h.prim);
    V4 col{1, 1, 1, 1};
    if (!m.colors.empty()) {
      auto c = [&](int k, int ch) {
        return float(m.colors[size_t(tri[k]) * 4 + size_t(ch)]) / 255.f;
      };
      col = {w0 * c(0, 0) + w1 * c(1, 0) + w2 * c(2, 0), w0 * c(0, 1) + w1 * c(1, 1) + w2 * c(2, 1),
             w0 * c(0, 2) + w1 * c(1, 2) + w2 * c(2, 2),
             w0 * c(0, 3) + w1 * c(1, 3) + w2 * c(2, 3)};
    }
    V4 base = V4{sm.diffuse[0], sm.diffuse[1], sm.diffuse[2], sm.diffuse[3]} * col;
    const auto& textures = *f_.textures;
    if (sm.texture >= 0 && size_t(sm.texture) < textures.size() && textures[size_t(sm.texture)]) {
      float uv[2] = {0, 0};
      if (!m.texcoords.empty()) {
        const float *p = &m.texcoords[size_t(tri[0]) * 2], *q = &m.texcoords[size_t(tri[1]) * 2],
                    *r = &m.texcoords[size_t(tri[2]) * 2];
        uv[0] = w0 * p[0] + w1 * q[0] + w2 * r[0];
        uv[1] = w0 * p[1] + w1 * q[1] + w2 * r[1];
      }
      base = base * sampleBilinear(*textures[size_t(sm.texture)], uv[0], uv[1]);
    }
    s.base = {base.r, base.g, base.b};
    s.nv = dot(n, s.v);
    s.nf = s.nv < 0 ? -n : n;
    s.p = dir * h.t + org;
    // Out of the surface by a little more than the float error of a
    // position of this magnitude.
    s.eps = 2e-5f * std::max({std::abs(s.p.x), std::abs(s.p.y), std::abs(s.p.z)}) + 1e-6f;
    s.effect = in.effect;
    return s;
  }

  // Whether the surface needs a shadow ray: shadows on and facing the light
  // (turned away, it is at ambient anyway). Its origin and direction.
  bool wantsShadowRay(const Surface& s) const { return f_.opts.shadows && dot(s.nf, f_.light) > 0; }
  V3 shadowOrigin(const Surface& s) const { return s.p + s.nf * s.eps; }

  // The colour of surface `s`, `depth` bounces in; `lit`: its shadow ray's
  // verdict (when wantsShadowRay).
  V3 light(const Surface& s, bool lit, int depth) {
    V3 local;
    if (f_.opts.shadows)
      local = s.base * (0.3f + 0.7f * (lit ? dot(s.nf, f_.light) : 0.f));
    else
      local = s.base * (0.3f + 0.7f * std::abs(s.nv));
    if (!f_.opts.reflections || s.effect == SurfaceEffect::None || depth >= f_.opts.max_depth)
      return local;

    const V3 nf = s.nf, p = s.p;
    V3 reflected = -s.v + nf * (2.f * dot(s.v, nf));
    if (s.effect == SurfaceEffect::Mirror)
      return local * 0.2f + trace(p + nf * s.eps, reflected, 0, depth + 1) * 0.8f;

    // Glass: entering where the ray meets the side the normal points to.
    const float eta = s.nv > 0 ? 1.f / 1.5f : 1.5f;
    const float cosi = std::abs(s.nv);
    const float k = 1.f - eta * eta * (1.f - cosi * cosi);
    float fresnel = 1.f;  // total internal reflection when k < 0
    V3 refr_col;
    if (k >= 0) {
      float cost = std::sqrt(k);
      V3 refracted = -s.v * eta + nf * (eta * cosi - cost);
      const float r0 = 0.04f;  // ((1 - 1.5) / (1 + 1.5))^2
      float c = 1.f - (eta < 1 ? cosi : cost);
      fresnel = r0 + (1 - r0) * c * c * c * c * c;
      refr_col = trace(p - nf * s.eps, refracted, 0, depth + 1) * s.base;
    }
    V3 refl_col = trace(p + nf * s.eps, reflected, 0, depth + 1);
    return refl_col * fresnel + refr_col * (1.f - fresnel);
  }

  V3 shade(const Hit& h, V3 org, V3 dir, int depth) {
    Surface s = surface(h, org, dir);
    bool lit = wantsShadowRay(s) && !occluded(shadowOrigin(s), f_.light);
    return light(s, lit, depth);
  }

 private:
  const Frame& f_;
};

}  // namespace

RtRenderStats RayTracer::render(const Camera& camera, int width, int height, const Rect& region,
                                const std::vector<RtInstance>& instances,
                                const std::vector<const TextureData*>& textures,
                                const RayOptions& opts, std::vector<uint8_t>* rgba, Rgb background,
                                uint64_t list_version) {
  if (width <= 0 || height <= 0 || !insideFrame(region, width, height))
    throw Error("ray tracer: region outside the " + std::to_string(width) + "x" +
                std::to_string(height) + " frame");
  if (opts.stride < 1 || opts.stride > kMaxRayStride)
    throw Error("ray tracer: stride " + std::to_string(opts.stride) + " outside 1 to " +
                std::to_string(kMaxRayStride));
  std::lock_guard<std::mutex> render_lock(impl_->render_mutex);
  rgba->assign(size_t(region.area()) * 4, 0);
  RtRenderStats stats;
  if (region.empty()) return stats;
  auto t0 = std::chrono::steady_clock::now();

  Frame f;
  f.textures = &textures;
  f.opts = opts;
  f.background = {background.r, background.g, background.b};
  {
    double ll = length(opts.light);
    Vec3d l = ll > 0 ? opts.light / ll : Vec3d{0, 0, 1};
    f.light = {float(l.x), float(l.y), float(l.z)};
  }

  // The top level: only what differs from the last call is touched.
  EmbreeDevice& d = *impl_->dev;
  TopLevel& top = impl_->top;
  {
    std::lock_guard<std::mutex> lock(d.mutex);
    d.check("an earlier call");
    if (instances.size() >= RTC_INVALID_GEOMETRY_ID)
      throw Error("ray tracer: too many objects (" + std::to_string(instances.size()) + ")");
    // A new anchor (every transform set again) when the eye's grid point
    // changes.
    const Vec3d anchor = anchorFor(camera.eye, opts.anchor_grid);
    if (!top.anchored || !(anchor == top.anchor)) {
      top.anchor = anchor;
      top.anchored = true;
      ++top.anchor_gen;
      stats.reanchored = true;
    }
    // The caller's promise: the same list as last time. Nothing to compare.
    const bool same =
        list_version != 0 && list_version == top.list_version && !stats.reanchored && !top.dirty;
    top.list_version = 0;  // until this call's update is complete
    if (!same) {
      const uint64_t stamp = ++top.stamp;
      const size_t last = top.order.size();
      top.order.resize(instances.size());
      for (size_t i = 0; i < instances.size(); ++i) {
        const RtInstance& in = instances[i];
        if (!in.mesh) continue;
        const uint32_t key = in.object != RtInstance::kNoObject ? in.object : uint32_t(i);
        uint32_t s = i < last ? top.order[i] : UINT32_MAX;
        if (s >= top.slots.size() || !top.slots[s].used || top.slots[s].key != key) {
          s = top.slotOf(key);
          if (s == TopLevel::kNoSlot) {
            if (!top.free.empty()) {
              s = top.free.back();
              top.free.pop_back();
            } else {
              RTCGeometry g = rtcNewGeometry(d.device, RTC_GEOMETRY_TYPE_INSTANCE);
              if (!g) {
                d.check("creating an instance");
                throw Error("Embree: creating an instance failed");
              }
              rtcSetGeometryInstancedScene(g, top.empty);
              rtcDisableGeometry(g);
              rtcCommitGeometry(g);
              s = uint32_t(top.slots.size());
              rtcAttachGeometryByID(top.scene, g, s);
              top.slots.push_back({});
              top.slots.back().geom = g;
              top.info.push_back({});
            }
            top.slots[s].used = true;
            top.slots[s].key = key;
            top.slots[s].anchor_gen = 0;  // no transform yet
            top.setSlotOf(key, s);
          }
        }
        TopSlot& t = top.slots[s];
        if (t.stamp == stamp)
          throw Error("ray tracer: object " + std::to_string(key) + " given twice in one frame");
        t.stamp = stamp;
        top.order[i] = s;
        // Checked where bound: a slot's mesh equal to this one was.
        if (static_cast<const RtMesh*>(t.mesh) != in.mesh) {
          const auto* mesh = dynamic_cast<const EmbreeMesh*>(in.mesh);
          if (!mesh || mesh->dev != impl_->dev)
            throw Error("ray tracer: an instance's mesh was built by another RayTracer");
          top.bind(s, mesh);
          ++stats.updated;
        }
        top.info[s].effect = in.effect;
        if (t.anchor_gen == top.anchor_gen && t.object_to_world == in.object_to_world) continue;
        // The transform less the anchor, in double, then float for Embree.
        Mat4d rel = in.object_to_world;
        for (int r = 0; r < 3; ++r) rel.at(r, 3) -= top.anchor[r];
        Mat4d inv;
        FrameInstance& fi = top.info[s];
        if (invertAffine(rel, &inv))  // normal matrix = inverse transpose of the 3x3
          for (int c = 0; c < 3; ++c)
            for (int r = 0; r < 3; ++r) fi.nrm[c * 3 + r] = float(inv.at(c, r));
        float xfm[12];  // 3x4 column-major
        for (int c = 0; c < 4; ++c)
          for (int r = 0; r < 3; ++r) xfm[c * 3 + r] = float(rel.at(r, c));
        rtcSetGeometryTransform(t.geom, 0, RTC_FORMAT_FLOAT3X4_COLUMN_MAJOR, xfm);
        rtcCommitGeometry(t.geom);
        t.object_to_world = in.object_to_world;
        t.anchor_gen = top.anchor_gen;
        top.dirty = true;
        ++stats.updated;
      }
      // Objects of the last call that are not in this one leave.
      for (uint32_t s = 0; s < top.slots.size(); ++s) {
        TopSlot& t = top.slots[s];
        if (!t.used || t.stamp == stamp) continue;
        top.bind(s, nullptr);
        t.used = false;
        top.setSlotOf(t.key, TopLevel::kNoSlot);
        top.free.push_back(s);
        ++stats.updated;
      }
    }
    if (top.dirty) {
      rtcCommitScene(top.scene);
      d.check("building the top level over " + std::to_string(instances.size()) + " objects");
      top.dirty = false;
      stats.rebuilt = true;
    }
    top.list_version = list_version;
  }
  f.scene = top.scene;
  f.instances = top.info.data();
  stats.top_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();

  // Primary rays from the eye (less the anchor), direction the eye-space
  // (ndc_x tan(fovy/2) aspect, ndc_y tan(fovy/2), -1) turned into world
  // space, so t is the eye-space depth and the near plane is tnear = near.
  const double ty = std::tan(camera.fovy_deg * M_PI / 360.0), tx = ty * camera.aspect;
  const float tnear = float(camera.near);
  const Mat4d rot = Mat4d::rotation(camera.rotation);  // camera to world
  const Vec3d eye_rel = camera.eye - top.anchor;
  const V3 org{float(eye_rel.x), float(eye_rel.y), float(eye_rel.z)};
  auto column = [&](int c) {
    return V3{float(rot.at(0, c)), float(rot.at(1, c)), float(rot.at(2, c))};
  };
  const V3 right = column(0), up = column(1), back = column(2);
  // The rays: one per pixel, or with a stride one per stride x stride block,
  // on a grid aligned to the frame (sample (i, j) is pixel (gx0 + i s,
  // gy0 + j s)) and one sample past the region's last pixel on each axis, so
  // that every pixel lies between four samples and a pixel's value does not
  // depend on the region (rayStrideGrid).
  const RayGrid grid = rayStrideGrid(region, opts.stride);
  const int st = grid.stride;
  std::vector<uint8_t> strided;
  std::vector<uint8_t>& samples = st == 1 ? *rgba : strided;
  if (st > 1) samples.assign(size_t(grid.w) * size_t(grid.h) * 4, 0);
  constexpr int kTile = 16;
  const int tiles_x = (grid.w + kTile - 1) / kTile, tiles_y = (grid.h + kTile - 1) / kTile;
  FlushDenormals ftz;
  impl_->pool->run(tiles_x * tiles_y, [&](int tile) {
    Tracer tracer(f);
    const int x0 = (tile % tiles_x) * kTile, y0 = (tile / tiles_x) * kTile;  // samples
    const int x1 = std::min(x0 + kTile, grid.w), y1 = std::min(y0 + kTile, grid.h);
    // 4x4 packets of coherent primary rays, then each ray's shading.
    for (int py = y0; py < y1; py += 4)
      for (int px = x0; px < x1; px += 4) {
        RTCRayHit16 rh;
        alignas(64) int valid[16];
        for (int k = 0; k < 16; ++k) {
          int i = px + (k & 3), j = py + (k >> 2);
          valid[k] = i < x1 && j < y1 ? -1 : 0;
          const int x = grid.x + i * st, y = grid.y + j * st;  // the sample's pixel
          float dx = float(((x + 0.5) / width * 2 - 1) * tx);
          float dy = float(((y + 0.5) / height * 2 - 1) * ty);
          V3 dir = right * dx + up * dy - back;
          rh.ray.org_x[k] = org.x;
          rh.ray.org_y[k] = org.y;
          rh.ray.org_z[k] = org.z;
          rh.ray.dir_x[k] = dir.x;
          rh.ray.dir_y[k] = dir.y;
          rh.ray.dir_z[k] = dir.z;
          rh.ray.tnear[k] = tnear;
          rh.ray.tfar[k] = std::numeric_limits<float>::infinity();
          rh.ray.time[k] = 0;
          rh.ray.mask[k] = 0xFFFFFFFFu;
          rh.ray.id[k] = unsigned(k);
          rh.ray.flags[k] = 0;
          rh.hit.geomID[k] = RTC_INVALID_GEOMETRY_ID;
          rh.hit.instID[0][k] = RTC_INVALID_GEOMETRY_ID;
        }
        RTCIntersectContext ctx;
        rtcInitIntersectContext(&ctx);
        // Embree's coherent (frustum) traversal: about 20% faster than the
        // default for these packets (docs/raytrace.md).
        ctx.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
        rtcIntersect16(valid, f.scene, &ctx, &rh);
        // Shading, with the shadow rays of the packet's surfaces traced as
        // one packet of their own.
        Tracer::Surface surf[16];
        alignas(64) int shadow_valid[16];
        RTCRay16 sh;
        bool any_shadow = false;
        for (int k = 0; k < 16; ++k) {
          // Every lane set, the invalid ones too (Embree loads all 16).
          shadow_valid[k] = 0;
          sh.org_x[k] = sh.org_y[k] = sh.org_z[k] = 0;
          sh.dir_x[k] = f.light.x;
          sh.dir_y[k] = f.light.y;
          sh.dir_z[k] = f.light.z;
          sh.tnear[k] = 0;
          sh.tfar[k] = std::numeric_limits<float>::infinity();
          sh.time[k] = 0;
          sh.mask[k] = 0xFFFFFFFFu;
          sh.id[k] = unsigned(k);
          sh.flags[k] = 0;
          if (!valid[k] || rh.hit.geomID[k] == RTC_INVALID_GEOMETRY_ID) continue;
          Hit h;
          h.hit = true;
          h.t = rh.ray.tfar[k];
          h.u = rh.hit.u[k];
          h.v = rh.hit.v[k];
          h.prim = rh.hit.primID[k];
          h.inst = rh.hit.instID[0][k];
          surf[k] = tracer.surface(h, org, V3{rh.ray.dir_x[k], rh.ray.dir_y[k], rh.ray.dir_z[k]});
          if (!tracer.wantsShadowRay(surf[k])) continue;
          V3 o = tracer.shadowOrigin(surf[k]);
          shadow_valid[k] = -1;
          any_shadow = true;
          sh.org_x[k] = o.x;
          sh.org_y[k] = o.y;
          sh.org_z[k] = o.z;
        }
        if (any_shadow) {
          RTCIntersectContext sctx;
          rtcInitIntersectContext(&sctx);
          // Not the coherent traversal: with it, rtcOccluded16 on these
          // packets (one direction, origins spread over a tile) never
          // returned in Embree 3.13.5 (any shadowed frame; not reproduced
          // outside the tracer, see docs/raytrace.md).
          sctx.flags = RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT;
          rtcOccluded16(shadow_valid, f.scene, &sctx, &sh);
        }
        for (int k = 0; k < 16; ++k) {
          if (!valid[k]) continue;
          int i = px + (k & 3), j = py + (k >> 2);
          V3 c = f.background;
          if (rh.hit.geomID[k] != RTC_INVALID_GEOMETRY_ID)
            c = tracer.light(surf[k], shadow_valid[k] && sh.tfar[k] >= 0, 0);
          uint8_t* out = &samples[(size_t(j) * size_t(grid.w) + size_t(i)) * 4];
          out[0] = unorm8(c.x);
          out[1] = unorm8(c.y);
          out[2] = unorm8(c.z);
          out[3] = 255;
        }
      }
  });
  if (st > 1) upsampleStrided(grid, samples.data(), region, rgba->data());
  return stats;
}

Vec3d anchorFor(Vec3d eye, double grid) {
  if (!(grid > 0)) return eye;
  auto snap = [grid](double v) { return std::nearbyint(v / grid) * grid; };
  return {snap(eye.x), snap(eye.y), snap(eye.z)};
}

RayGrid rayStrideGrid(const Rect& region, int stride) {
  if (stride <= 1 || region.empty()) return {region.x, region.y, region.w, region.h, 1};
  auto first = [&](int p) { return p / stride; };  // region coordinates are >= 0
  int i0 = first(region.x), j0 = first(region.y);
  return {i0 * stride, j0 * stride, first(region.x1() - 1) - i0 + 2,
          first(region.y1() - 1) - j0 + 2, stride};
}

void upsampleStrided(const RayGrid& g, const uint8_t* samples, const Rect& region, uint8_t* rgba) {
  const float inv = 1.f / float(g.stride);
  for (int y = region.y; y < region.y1(); ++y) {
    const int j = (y - g.y) / g.stride;
    const float fy = float(y - g.y - j * g.stride) * inv;
    for (int x = region.x; x < region.x1(); ++x) {
      const int i = (x - g.x) / g.stride;
      const float fx = float(x - g.x - i * g.stride) * inv;
      const uint8_t* a = &samples[(size_t(j) * size_t(g.w) + size_t(i)) * 4];
      const uint8_t* b = a + 4;
      const uint8_t* c = a + size_t(g.w) * 4;
      const uint8_t* d = c + 4;
      uint8_t* out = &rgba[(size_t(y - region.y) * size_t(region.w) + size_t(x - region.x)) * 4];
      for (int ch = 0; ch < 4; ++ch) {
        float top = a[ch] + (b[ch] - a[ch]) * fx, bottom = c[ch] + (d[ch] - c[ch]) * fx;
        out[ch] = uint8_t(top + (bottom - top) * fy + 0.5f);
      }
    }
  }
}

}  // namespace dmmr
