// Procedural test scenes for dmmr: an industrial plant in the spirit of the
// UNC Power Plant model, a monument site, and instanced replication of any
// scene, plus fixed camera paths through them.
//
// Conventions for every generated scene: metres, Z up, origin at the ground
// centre. Each osg::Geode holds exactly one osg::Geometry with one GL_TRIANGLES
// DrawElementsUShort (or DrawElementsUInt past 65536 vertices). Curved parts
// (pipes, tanks, columns, domes) carry per-vertex normals; flat parts (boxes,
// walls, floors, beams, stairs) carry no normals array at all. Every geode's
// StateSet has an osg::Material whose diffuse colour comes from a palette of 8;
// StateSets are shared between geodes of the same colour. A few geodes (~3%)
// also carry per-vertex colours (BIND_PER_VERTEX; their Material uses
// ColorMode AMBIENT_AND_DIFFUSE).
//
// Determinism: the same parameters give an identical scene (same node order,
// names, matrices and vertex arrays) on a given platform; the generators use
// splitmix64 with their own uniform mapping, no <random> distributions.
#pragma once

#include <cstdint>

#include <osg/BoundingBox>
#include <osg/Geometry>
#include <osg/Node>
#include <osg/ref_ptr>

#include "walkthrough.h"

namespace dmmr::scenegen {

struct PlantParams {
  uint64_t seed = 1;
  uint64_t triangles = 1'000'000;  // target total; the result is within ~5%
  uint32_t geodes = 20000;         // target geode count
};

// An industrial plant about 100 x 100 x 40 m: 2x2 sections (rotated by
// multiples of 90 degrees), 4 storeys of 10 m, each storey a grid of bays with
// floor slabs, columns, beams, walls with openings, stairs, and densely packed
// equipment units (tanks, vessels, pumps, heat exchangers, pipe racks, ducts,
// valve manifolds, cabinets, pipe runs with elbows). Hierarchy (8 levels):
// plant / section (MatrixTransform) / storey (MatrixTransform) / row / bay
// (MatrixTransform) / unit (MatrixTransform, translated and rotated about Z) /
// cluster / Geode.
// Exactly `geodes` geodes are made, unless the triangle budget cannot give
// every geode its coarsest tessellation (about 45 triangles per geode on
// average; 4-sided pipes); the geode count is then lowered until it can.
// Tessellation (ring segments, rings along lengths, elbow and dome steps) is
// scaled by one global detail factor chosen so the total triangle count lands
// near `triangles` (measured: within 1% from 50k to 20M). Structure (floors,
// walls, beams, stairs) takes at most half of each bay's geodes; with fewer
// than ~50 geodes the plant is all floors and the target may not be reached.
// Cost: ~0.3 s and 110 MB for 1M triangles, ~1 s and 330 MB for 10M.
// Throws dmmr::Error when triangles or geodes is 0 or triangles > 2e9.
osg::ref_ptr<osg::Node> makePlant(const PlantParams& params);

struct MonumentParams {
  uint64_t seed = 1;
  uint64_t triangles = 1'000'000;
  uint32_t geodes = 1000;
};

// A monument site about 400 x 400 x 40 m: perimeter walls with crenellations,
// corner towers and gateways with arches, courtyards of ground slabs, a central
// domed rotunda ringed by fluted columns, and per-courtyard pavilions
// (tholoi), stoas (colonnades) and fountains with obelisks. Fewer, heavier
// geodes than the plant: walls and slabs are grid-subdivided, columns finely
// tessellated. Hierarchy: monument / quarter (MatrixTransform, rotated by k*90
// degrees) / courtyard / structure (MatrixTransform) / part / column
// (MatrixTransform) / Geode. Geode and triangle targets behave as in makePlant.
osg::ref_ptr<osg::Node> makeMonument(const MonumentParams& params);

// `copies` instances of `input` on a near-square grid in the XY plane, centred
// on the input's own position: an osg::Group of osg::MatrixTransforms
// (translation only), each with the SAME `input` pointer as its single child,
// so the geometry is stored once in memory and in .osgb files. spacing <= 0
// means automatic: the input's bounding sphere diameter * 1.1 (1.0 when the
// diameter is 0). Throws dmmr::Error when input is null, copies == 0, the
// input's bounds are empty (no geometry), or spacing is not finite.
osg::ref_ptr<osg::Node> replicate(osg::Node* input, uint32_t copies, double spacing);

// A copy of `input` in which every geode's osg::Geometry is replaced by one
// whose triangles are each cut into n * n: every edge into n equal parts,
// new points on the triangle's plane, per-vertex normals, colours and unit-0
// texture coordinates interpolated linearly (in double). Points on an edge
// are computed from its end points in one order and shared by the
// triangles on both sides, so no cracks open; winding is kept. Makes one
// dense mesh of a scanned model (the skull's 100k triangles, n = 5: 2.5M)
// for testing clustering. Geometries that are not triangles over a Vec3Array
// are kept as they are; scene-graph nodes other than geodes are shared with
// `input`. n = 1 returns `input` itself. Throws dmmr::Error when input is null or n
// is 0 or over 1000.
osg::ref_ptr<osg::Node> subdivide(osg::Node* input, uint32_t n);

enum class PathKind {
  // From 0.2 of the X extent outside the box's -X side to 0.9 of the way
  // across, at one third of the height, with a gentle turn (Y follows a
  // parabola, heading within ~25 degrees of +X), looking forward and 10 degrees
  // down. On the middle frame the camera is at 0.35 of the X extent and 0.05 of
  // the Y extent off the centre, heading +X, so the centre lies ahead. For
  // plants, monuments and replicated scenes.
  FlyThrough,
  // A full circle around the box centre at 2.2 * half its diagonal, 20 degrees
  // above the horizon, always looking at the centre. For arbitrary models.
  Orbit,
  // A full circle around the box centre, close: radius 0.8 of half the XY
  // diagonal, a quarter of the height above the centre, always looking at
  // the centre. Around a 2x2 `replicate` grid it passes each copy at about
  // a fifth of its size (the copy fills the view) and between neighbours.
  Around,
};

// Bounds of all geometry under `node`, transforms applied.
osg::BoundingBox sceneBounds(osg::Node& node);

// `frames` control points, time i/30 s, unit quaternions from
// dmmr::lookAtRotation (camera looks down local -Z, +Y up). Throws dmmr::Error
// when frames == 0 or the box is invalid.
Walkthrough makeWalkthrough(const osg::BoundingBox& bounds, uint32_t frames, PathKind kind);

struct SceneStats {
  uint64_t geodes = 0;              // distinct Geode objects
  uint64_t geodeInstances = 0;      // geodes counted once per path from the root
  uint64_t geometries = 0;          // distinct Geometry objects
  uint64_t triangles = 0;           // over distinct geometries
  uint64_t instancedTriangles = 0;  // over all instances
};

// Counts what a traversal from `node` reaches (all children, all switches).
SceneStats sceneStats(osg::Node& node);

// Triangles drawn by `geometry`'s primitive sets (strips and fans included).
uint64_t countTriangles(const osg::Geometry& geometry);

}  // namespace dmmr::scenegen
