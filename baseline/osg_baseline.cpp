#include "osg_baseline.h"

#include <GL/osmesa.h>
#include <dlfcn.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <map>
#include <osg/ComputeBoundsVisitor>
#include <osg/Geometry>
#include <osg/LightModel>
#include <osg/OcclusionQueryNode>
#include <osgDB/ReadFile>
#include <osgDB/Registry>
#include <osgUtil/SceneView>
#include <osgUtil/Statistics>
#include <osgViewer/Renderer>
#include <osgViewer/Viewer>
#include <vector>

#include "atomic_file.h"
#include "error.h"
#include "image.h"

// OSG looks its GL extension entry points up with glXGetProcAddressARB
// (found with dlsym in the global scope, osg/GLExtensions.cpp), which would
// answer with libGL's GLX dispatch stubs: they do nothing in an OSMesa
// context. This definition comes first in the global scope (the executable
// exports it, see baseline/CMakeLists.txt) and answers with OSMesa's entry
// points. OSG's direct calls of GL 1.x functions resolve to libOSMesa because
// it is linked before OSG; runOsgViewer checks both at start.
extern "C"
    __attribute__((visibility("default"))) void (*glXGetProcAddressARB(const GLubyte* name))() {
  return reinterpret_cast<void (*)()>(OSMesaGetProcAddress(reinterpret_cast<const char*>(name)));
}
extern "C" __attribute__((visibility("default"))) void (*glXGetProcAddress(const GLubyte* name))() {
  return glXGetProcAddressARB(name);
}

namespace dmmr {

namespace {

using Clock = std::chrono::steady_clock;
double msSince(Clock::time_point t) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t).count();
}

// dmmr's background (common/draw.h, Renderer::beginFrame's default Rgb), so
// that the frames of both look alike where nothing is drawn.
const osg::Vec4 kBackground(0.2f, 0.22f, 0.26f, 1.f);

class VertexCounter : public osg::NodeVisitor {
 public:
  explicit VertexCounter(uint64_t limit) : osg::NodeVisitor(TRAVERSE_ALL_CHILDREN), limit_(limit) {}
  uint64_t total() const { return total_; }
  void apply(osg::Node& node) override {
    if (total_ <= limit_) traverse(node);
  }
  void apply(osg::Geometry& g) override {
    if (total_ > limit_) return;
    if (const osg::Array* v = g.getVertexArray()) total_ += v->getNumElements();
  }

 private:
  uint64_t limit_, total_ = 0;
};

// Bottom-up placement, after the osgocclusionquery example's
// OcclusionQueryVisitor, with instances handled once (see the header).
class OcclusionQueryInserter : public osg::NodeVisitor {
 public:
  explicit OcclusionQueryInserter(const OcclusionSettings& s)
      : osg::NodeVisitor(TRAVERSE_ALL_CHILDREN), settings_(s) {
    // One query and one debug state set for all, as the example shares them:
    // those a default OcclusionQueryNode makes.
    osg::ref_ptr<osg::OcclusionQueryNode> proto = new osg::OcclusionQueryNode;
    query_state_ = proto->getQueryStateSet();
    debug_state_ = proto->getDebugStateSet();
  }
  uint32_t added() const { return added_; }

  void apply(osg::OcclusionQueryNode& oqn) override { covered_[&oqn] = true; }
  void apply(osg::Group& group) override {
    if (covered_.count(&group)) return;  // a shared subgraph, already placed
    traverse(group);
    bool below = false;
    for (unsigned i = 0; i < group.getNumChildren(); ++i) {
      auto it = covered_.find(group.getChild(i));
      below = below || (it != covered_.end() && it->second);
    }
    if (!below && group.getNumParents() > 0 &&
        countVertices(group, settings_.min_vertices) > settings_.min_vertices) {
      // A copy (replacing a child edits the list).
      osg::Node::ParentList parents = group.getParents();
      osg::ref_ptr<osg::Group> keep = &group;
      for (osg::Group* parent : parents) {
        osg::ref_ptr<osg::OcclusionQueryNode> oqn = new osg::OcclusionQueryNode;
        oqn->setName("oqn" + std::to_string(added_++));
        oqn->setVisibilityThreshold(settings_.visibility_threshold);
        oqn->setQueryFrameCount(settings_.query_frame_count);
        oqn->setQueryStateSet(query_state_.get());
        oqn->setDebugStateSet(debug_state_.get());
        oqn->addChild(&group);
        parent->replaceChild(&group, oqn.get());
        covered_[oqn.get()] = true;
      }
      below = true;
    }
    covered_[&group] = below;
  }

 private:
  OcclusionSettings settings_;
  osg::ref_ptr<osg::StateSet> query_state_, debug_state_;
  std::map<const osg::Node*, bool> covered_;  // an OcclusionQueryNode at or below
  uint32_t added_ = 0;
};

// OSG computes near and far from the bounding volumes it draws (its default,
// the tightest depth range); the near plane is then kept no closer than
// dmmr's, and the projection rebuilt with the run's fovy and aspect.
class NearClamp : public osg::CullSettings::ClampProjectionMatrixCallback {
 public:
  NearClamp(double fovy, double aspect, double min_near)
      : fovy_(fovy), aspect_(aspect), min_near_(min_near) {}
  bool clampProjectionMatrixImplementation(osg::Matrixf& p, double& n, double& f) const override {
    osg::Matrixd d(p);
    if (!clamp(d, n, f)) return false;
    p = osg::Matrixf(d);
    return true;
  }
  bool clampProjectionMatrixImplementation(osg::Matrixd& p, double& n, double& f) const override {
    return clamp(p, n, f);
  }

 private:
  bool clamp(osg::Matrixd& p, double& znear, double& zfar) const {
    if (!(zfar > 0) || !std::isfinite(zfar)) return false;  // nothing in front of the eye
    // OSG's own margins (CullVisitor::clampProjectionMatrixImplementation).
    double n = std::max(znear * 0.98, min_near_);
    double f = std::max(zfar * 1.02, n * 1.01);
    p.makePerspective(fovy_, aspect_, n, f);
    znear = n;
    zfar = f;
    return true;
  }
  double fovy_, aspect_, min_near_;
};

// OSMesa context of the compatibility profile (OSG 3.6 as packaged draws
// with the fixed-function pipeline), drawing into a W x H RGBA buffer.
class OSMesaTarget {
 public:
  OSMesaTarget(int w, int h) : buffer_(size_t(w) * h * 4) {
    const int attribs[] = {OSMESA_FORMAT,
                           OSMESA_RGBA,
                           OSMESA_DEPTH_BITS,
                           24,
                           OSMESA_STENCIL_BITS,
                           8,
                           OSMESA_PROFILE,
                           OSMESA_COMPAT_PROFILE,
                           0};
    ctx_ = OSMesaCreateContextAttribs(attribs, nullptr);
    if (!ctx_) throw Error("osmesa: cannot create an OpenGL compatibility context");
    if (!OSMesaMakeCurrent(ctx_, buffer_.data(), GL_UNSIGNED_BYTE, w, h))
      throw Error("osmesa: cannot make the context current");
    finish_ = reinterpret_cast<void (*)()>(OSMesaGetProcAddress("glFinish"));
    read_ = reinterpret_cast<void (*)(GLint, GLint, GLsizei, GLsizei, GLenum, GLenum, void*)>(
        OSMesaGetProcAddress("glReadPixels"));
    if (!finish_ || !read_) throw Error("osmesa: no glFinish or glReadPixels");
  }
  ~OSMesaTarget() { OSMesaDestroyContext(ctx_); }
  OSMesaTarget(const OSMesaTarget&) = delete;
  OSMesaTarget& operator=(const OSMesaTarget&) = delete;

  void finish() const { finish_(); }
  void read(int w, int h, std::vector<uint8_t>* bottom_up) const {
    bottom_up->resize(size_t(w) * h * 4);
    read_(0, 0, w, h, GL_RGBA, GL_UNSIGNED_BYTE, bottom_up->data());
  }

 private:
  OSMesaContext ctx_ = nullptr;
  std::vector<unsigned char> buffer_;
  void (*finish_)() = nullptr;
  void (*read_)(GLint, GLint, GLsizei, GLsizei, GLenum, GLenum, void*) = nullptr;
};

// OSG's GL calls must reach OSMesa (see glXGetProcAddressARB above).
void checkGlResolution() {
  Dl_info info{};
  void* direct = dlsym(RTLD_DEFAULT, "glGetString");
  if (!direct || !dladdr(direct, &info) || !info.dli_fname ||
      !std::strstr(info.dli_fname, "OSMesa"))
    throw Error(std::string("GL functions resolve to ") +
                (info.dli_fname ? info.dli_fname : "nothing") +
                ", not libOSMesa: link libOSMesa before OpenSceneGraph");
  using Gpa = void* (*)(const char*);
  auto gpa = reinterpret_cast<Gpa>(dlsym(RTLD_DEFAULT, "glXGetProcAddressARB"));
  if (!gpa || gpa("glGenQueries") != reinterpret_cast<void*>(OSMesaGetProcAddress("glGenQueries")))
    throw Error("glXGetProcAddressARB does not answer with OSMesa's entry points");
}

Image toImage(int w, int h, const std::vector<uint8_t>& bottom_up) {
  Image img = flipRows(Image{w, h, bottom_up});
  for (size_t p = 3; p < img.rgba.size(); p += 4) img.rgba[p] = 255;  // opaque, as dmmr's
  return img;
}

osg::ref_ptr<osg::Node> readModel(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec))
    throw Error(fileError(path, "cannot open model (no such file, or not a regular file)"));
  auto* reg = osgDB::Registry::instance();
  osgDB::ReaderWriter::ReadResult r = reg->readNode(path, reg->getOptions());
  if (!r.validNode()) {
    std::string why = r.message().empty() ? "" : " (" + r.message() + ")";
    throw Error(fileError(path, "cannot read as a model" + why));
  }
  return r.getNode();
}

uint64_t trianglesOf(const osgUtil::Statistics& st) {
  const auto& pcm = st.getPrimitiveCountMap();
  uint64_t t = 0;
  for (GLenum mode : {GLenum(GL_TRIANGLES), GLenum(GL_TRIANGLE_STRIP), GLenum(GL_TRIANGLE_FAN)})
    if (auto it = pcm.find(mode); it != pcm.end()) t += it->second;
  return t;
}

}  // namespace

uint64_t countVertices(osg::Node& node, uint64_t limit) {
  VertexCounter vc(limit);
  node.accept(vc);
  return vc.total();
}

uint32_t insertOcclusionQueries(osg::Node& root, const OcclusionSettings& settings) {
  OcclusionQueryInserter ins(settings);
  root.accept(ins);
  return ins.added();
}

osg::Matrixd osgViewMatrix(const ControlPoint& p) {
  osg::Quat q(p.rotation.x, p.rotation.y, p.rotation.z, p.rotation.w);
  osg::Vec3d eye(p.position.x, p.position.y, p.position.z);
  return osg::Matrixd::inverse(osg::Matrixd::rotate(q) * osg::Matrixd::translate(eye));
}

void runOsgViewer(const OsgViewerOptions& opts) {
  const int w = opts.view.width, h = opts.view.height;
  Walkthrough path = readWalkthrough(opts.walkthrough);
  osg::ref_ptr<osg::Group> root = new osg::Group;  // so that the model's root can get a query
  root->addChild(readModel(opts.model));
  // Two-sided lighting, as dmmr's headlight shading is (back faces are lit
  // too).
  osg::ref_ptr<osg::LightModel> lm = new osg::LightModel;
  lm->setTwoSided(true);
  root->getOrCreateStateSet()->setAttributeAndModes(lm.get());
  uint32_t queries = opts.occlusion ? insertOcclusionQueries(*root, opts.queries) : 0;

  osg::ComputeBoundsVisitor cbv;
  root->accept(cbv);
  const osg::BoundingBox& box = cbv.getBoundingBox();
  double diag = box.valid() ? (box._max - box._min).length() : 0;
  double near = opts.view.near > 0 ? opts.view.near : (diag > 0 ? diag * 1e-5 : 1e-3);
  double aspect = double(w) / double(h);

  std::filesystem::create_directories(opts.out);
  std::string csv = "frame,frame_ms,draw_ms,drawables,triangles\n";
  if (!opts.stats.empty()) writeFileAtomic(opts.stats, csv);  // fails early on a bad path

  OSMesaTarget target(w, h);
  checkGlResolution();

  osgViewer::Viewer viewer;
  viewer.setThreadingModel(osgViewer::ViewerBase::SingleThreaded);
  viewer.setUpViewerAsEmbeddedInWindow(0, 0, w, h);
  viewer.setSceneData(root.get());
  osg::Camera* cam = viewer.getCamera();
  cam->setClearColor(kBackground);
  cam->setComputeNearFarMode(osg::CullSettings::COMPUTE_NEAR_FAR_USING_BOUNDING_VOLUMES);
  cam->setClampProjectionMatrixCallback(new NearClamp(opts.view.fovy_deg, aspect, near));
  viewer.realize();
  if (!viewer.isRealized()) throw Error("osgViewer: cannot realize the embedded window");
  auto* renderer = dynamic_cast<osgViewer::Renderer*>(cam->getRenderer());

  if (opts.progress)
    std::fprintf(stderr, "dmmr-osgviewer: %s, %u occlusion query nodes, %zu frames\n",
                 opts.model.c_str(), queries, path.points.size());
  std::vector<uint8_t> pixels;
  for (size_t f = 0; f < path.points.size(); ++f) {
    auto t0 = Clock::now();
    const ControlPoint& p = path.points[f];
    cam->setViewMatrix(osgViewMatrix(p));
    // The far plane here only matters when nothing is drawn; OSG computes
    // near and far from what it draws (NearClamp).
    double far = std::max(
        near * 2,
        (osg::Vec3d(p.position.x, p.position.y, p.position.z) - osg::Vec3d(box.center())).length() +
            diag);
    cam->setProjectionMatrixAsPerspective(opts.view.fovy_deg, aspect, near, far);
    viewer.frame();
    target.finish();
    target.read(w, h, &pixels);
    double draw_ms = msSince(t0);
    writePng(opts.out + "/" + frameFileName(f), toImage(w, h, pixels));
    double frame_ms = msSince(t0);

    // What was drawn: the render graph of this frame's cull (query boxes are
    // quads and not counted as triangles).
    osgUtil::Statistics st;
    if (renderer && renderer->getSceneView(0)) renderer->getSceneView(0)->getStats(st);
    char line[160];
    std::snprintf(line, sizeof line, "%zu,%.3f,%.3f,%d,%llu\n", f, frame_ms, draw_ms,
                  st.numDrawables, static_cast<unsigned long long>(trianglesOf(st)));
    csv += line;
    if (!opts.stats.empty()) writeFileAtomic(opts.stats, csv);  // flushed as frames finish
    if (opts.progress)
      std::fprintf(stderr, "\rdmmr-osgviewer: frame %zu/%zu (%.0f ms)", f + 1, path.points.size(),
                   frame_ms);
  }
  if (opts.progress) std::fprintf(stderr, "\n");
}

}  // namespace dmmr
