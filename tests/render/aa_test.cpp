// Anti-aliasing on the Vulkan device (lavapipe in CI) with validation on. The edge scene
// (renderer/scene/edge_scene.h) is scored against a supersampled reference: the same frame
// without AA at 4x width and height, box-filtered down in linear light (16 samples a pixel).
// Its edge mask, the pixels where the reference and the no-AA frame differ, is where AA has
// work to do; everything else must come out as without AA. Each mode's figures are printed.
//
// vis_mlaa also has a golden image (tests/render/golden/vis_mlaa_demo.png): set
// TESSERA_UPDATE_GOLDENS=1 to rewrite it (then look at it before committing it). On a mismatch
// the actual image and an amplified diff are written to $TESSERA_TEST_OUTPUT_DIR.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "renderer/camera.h"
#include "renderer/image_io.h"
#include "renderer/image_metrics.h"
#include "renderer/renderer.h"
#include "renderer/scene/city_scene.h"
#include "renderer/scene/cpu_scene.h"
#include "renderer/scene/edge_scene.h"
#include "shared_renderer.h"
#include "tests/render/golden.h"

namespace tessera {
namespace {

// Every note of a frame, for failure messages.
std::string Notes(const Frame& f) {
  std::string out;
  for (const SettingNote& n : f.settings.notes) out += " [" + n.field + ": " + n.message + "]";
  return out.empty() ? " (no notes)" : out;
}

// As render_test.cpp: compares with tests/render/golden/<name>.png, or writes it when
// TESSERA_UPDATE_GOLDENS=1 (the test is then reported as skipped).

// ---------------------------------------------------------------------------------------------
// The edge scene, its no-AA frame, its supersampled reference and its edge mask: made once per
// binary (the 4x reference is the costly frame).

struct EdgeData {
  EdgeScene edges;
  SceneHandle scene;
  Camera camera;
  RgbaImage none;                  // aa none, base colour
  RgbaImage reference;             // aa none at 4x width and height, DownsampleBox(.., 4)
  std::vector<uint8_t> edge_mask;  // DifferenceMask(reference, none)
  double none_edge_psnr = 0.0;
  double none_coverage_mae = 0.0;
};

// The edge scene at its own size, with the base-colour debug view: a pixel's linear value is
// the rendered coverage of the white shapes.
Settings EdgeSettings(const EdgeScene& e, AaMode aa, uint32_t samples = 4,
                      DebugView view = DebugView::kBaseColor) {
  Settings s;
  s.width = e.width;
  s.height = e.height;
  s.aa = aa;
  s.samples = samples;
  s.debug_view = view;
  return s;
}

std::unique_ptr<EdgeData> MakeEdgeData() {
  Renderer& r = SharedRenderer();
  auto d = std::make_unique<EdgeData>();
  d->edges = BuildEdgeScene();
  const EdgeScene& e = d->edges;
  absl::StatusOr<SceneHandle> scene = r.LoadScene(e.scene);
  if (!scene.ok()) {
    ADD_FAILURE() << "edge scene: " << scene.status();
    return nullptr;
  }
  d->scene = *scene;
  d->camera.eye = e.eye;
  d->camera.target = e.target;
  d->camera.yfov = e.yfov;
  d->camera.znear = e.znear;

  absl::StatusOr<Frame> none = r.Render(*d->scene, d->camera, EdgeSettings(e, AaMode::kNone));
  Settings big = EdgeSettings(e, AaMode::kNone);
  big.width *= 4;
  big.height *= 4;
  absl::StatusOr<Frame> big_frame = r.Render(*d->scene, d->camera, big);
  if (!none.ok() || !big_frame.ok()) {
    ADD_FAILURE() << "edge scene frames: " << none.status() << " / " << big_frame.status();
    return nullptr;
  }
  absl::StatusOr<RgbaImage> reference = DownsampleBox(big_frame->image, 4);
  if (!reference.ok()) {
    ADD_FAILURE() << "reference: " << reference.status();
    return nullptr;
  }
  d->none = std::move(none->image);
  d->reference = std::move(*reference);
  absl::StatusOr<std::vector<uint8_t>> mask = DifferenceMask(d->reference, d->none);
  absl::StatusOr<double> psnr =
      mask.ok() ? PsnrMasked(d->none, d->reference, *mask) : absl::StatusOr<double>(mask.status());
  absl::StatusOr<CoverageError> coverage = MeasureCoverage(d->none, e.coverage);
  if (!psnr.ok() || !coverage.ok()) {
    ADD_FAILURE() << "edge metrics: " << psnr.status() << " / " << coverage.status();
    return nullptr;
  }
  d->edge_mask = std::move(*mask);
  d->none_edge_psnr = *psnr;
  d->none_coverage_mae = coverage->edge_mae;
  return d;
}

// nullptr when setting up failed (reported once, by the first test that asked).
const EdgeData* SharedEdges() {
  static const std::unique_ptr<EdgeData> data = MakeEdgeData();
  return data.get();
}

// PSNR against the reference over the edge mask.
double EdgePsnr(const EdgeData& d, const RgbaImage& image) {
  absl::StatusOr<double> p = PsnrMasked(image, d.reference, d.edge_mask);
  EXPECT_TRUE(p.ok()) << p.status();
  return p.ok() ? *p : std::nan("");
}

// Mean absolute coverage error over the edge pixels, against the analytic coverage.
double CoverageMae(const EdgeData& d, const RgbaImage& image) {
  absl::StatusOr<CoverageError> c = MeasureCoverage(image, d.edges.coverage);
  EXPECT_TRUE(c.ok()) << c.status();
  return c.ok() ? c->edge_mae : std::nan("");
}

// Renders the edge scene; the mode must not have been changed (the assertions about a mode are
// meaningless for another).
absl::StatusOr<Frame> RenderEdges(const EdgeData& d, const Settings& s, uint64_t view = 0) {
  absl::StatusOr<Frame> f = SharedRenderer().Render(*d.scene, d.camera, s, view);
  if (f.ok()) {
    EXPECT_EQ(f->settings.effective.aa, s.aa) << ToString(s.aa) << ":" << Notes(*f);
    EXPECT_FALSE(HasNote(*f, "aa")) << ToString(s.aa) << ":" << Notes(*f);
  }
  return f;
}

// Each mode against the supersampled reference: vis_mlaa and msaa close most of the gap on the
// edges, fxaa some of it; vis_mlaa leaves every other pixel as it was without AA.
TEST(AaTest, EdgeScene) {
  const EdgeData* d = SharedEdges();
  ASSERT_NE(d, nullptr) << "edge scene set-up failed (see the first failure)";
  Renderer& r = SharedRenderer();
  const EdgeScene& e = d->edges;
  const uint64_t edge_pixels = MaskCount(d->edge_mask);
  ASSERT_GT(edge_pixels, 0u) << "the reference and the no-AA frame agree everywhere";
  ASSERT_LT(edge_pixels, uint64_t(e.width) * e.height / 2) << "the edge mask selects most pixels";

  absl::StatusOr<Frame> msaa = RenderEdges(*d, EdgeSettings(e, AaMode::kMsaa, 4));
  absl::StatusOr<Frame> fxaa = RenderEdges(*d, EdgeSettings(e, AaMode::kFxaa));
  ASSERT_TRUE(msaa.ok()) << msaa.status();
  ASSERT_TRUE(fxaa.ok()) << fxaa.status();
  const double none_psnr = d->none_edge_psnr;
  const double msaa_psnr = EdgePsnr(*d, msaa->image);
  const double fxaa_psnr = EdgePsnr(*d, fxaa->image);
  const double none_mae = d->none_coverage_mae;
  const double msaa_mae = CoverageMae(*d, msaa->image);
  const double fxaa_mae = CoverageMae(*d, fxaa->image);
  const double reference_mae = CoverageMae(*d, d->reference);

  std::printf("edge scene %ux%u, %llu edge pixels (reference: 4x4 supersampled)\n", e.width,
              e.height, static_cast<unsigned long long>(edge_pixels));
  std::printf("  %-9s samples  edge PSNR dB  coverage MAE\n", "mode");
  std::printf("  %-9s %7u  %12.2f  %12.4f\n", "none", 1u, none_psnr, none_mae);
  std::printf("  %-9s %7u  %12.2f  %12.4f\n", "msaa", msaa->settings.effective.samples, msaa_psnr,
              msaa_mae);
  std::printf("  %-9s %7u  %12.2f  %12.4f\n", "fxaa", 1u, fxaa_psnr, fxaa_mae);
  std::printf("  %-9s %7u  %12s  %12.4f\n", "reference", 16u, "-", reference_mae);
  EXPECT_GE(msaa_psnr, none_psnr + 6.0) << "msaa " << msaa_psnr << " dB, none " << none_psnr;
  EXPECT_GT(fxaa_psnr, none_psnr) << "fxaa " << fxaa_psnr << " dB, none " << none_psnr;
  // The analytic coverage is of the rasterizer's own pixel grid: a half-pixel offset or a
  // mis-scaled layout would show here as an error of ~0.25 or more.
  EXPECT_LT(reference_mae, 0.03) << "the reference's coverage MAE";

  if (r.device_info().visibility_buffer) {
    absl::StatusOr<Frame> vis = RenderEdges(*d, EdgeSettings(e, AaMode::kVisMlaa, 4));
    ASSERT_TRUE(vis.ok()) << vis.status();
    ASSERT_EQ(vis->settings.effective.aa, AaMode::kVisMlaa) << Notes(*vis);
    const double vis_psnr = EdgePsnr(*d, vis->image);
    const double vis_mae = CoverageMae(*d, vis->image);
    // Off the edges: where neither the reference nor msaa at the same samples differs from
    // none. A device that snaps vertices to a coarser sub-pixel grid (SwiftShader) puts a wire's
    // sliver over one of a pixel's 4 samples where the 4x-wide reference, snapped on a grid 4
    // times finer, misses it: msaa shows it there as vis_mlaa does (8 such pixels).
    absl::StatusOr<std::vector<uint8_t>> msaa_edges = DifferenceMask(msaa->image, d->none);
    ASSERT_TRUE(msaa_edges.ok()) << msaa_edges.status();
    std::vector<uint8_t> off_edges = InvertMask(d->edge_mask);
    for (size_t i = 0; i < off_edges.size(); ++i) off_edges[i] &= uint8_t(!(*msaa_edges)[i]);
    absl::StatusOr<double> vis_rest = PsnrMasked(vis->image, d->none, off_edges);
    ASSERT_TRUE(vis_rest.ok()) << vis_rest.status();
    std::printf("  %-9s %7u  %12.2f  %12.4f\n", "vis_mlaa", vis->settings.effective.samples,
                vis_psnr, vis_mae);
    std::printf("  vis_mlaa vs none off the edges: %.2f dB\n", *vis_rest);
    EXPECT_GE(vis_psnr, none_psnr + 6.0) << "vis_mlaa " << vis_psnr << " dB, none " << none_psnr;
    EXPECT_GT(vis_psnr, fxaa_psnr) << "vis_mlaa " << vis_psnr << " dB, fxaa " << fxaa_psnr;
    EXPECT_GE(*vis_rest, 50.0) << "vis_mlaa changed pixels away from the edges";
    EXPECT_LT(vis_mae, none_mae) << "vis_mlaa coverage MAE " << vis_mae << ", none " << none_mae;
  }
  ExpectNoValidationMessages(r);
}

// The rows of the edge scene's wire cells (the last kWireShapes shapes): the image's rows and the
// analytic coverage there, for MeasureCoverage over the wires alone.
constexpr size_t kWireShapes = 8;
struct WireRows {
  uint32_t y0 = 0, y1 = 0;  // [y0, y1)
};
WireRows WireRowsOf(const EdgeScene& e) {
  double lo = 1e9, hi = -1e9;
  for (size_t i = e.shapes.size() - kWireShapes; i < e.shapes.size(); ++i) {
    for (const PixelPoint& q : e.shapes[i]) {
      lo = std::min(lo, q.y);
      hi = std::max(hi, q.y);
    }
  }
  return {uint32_t(std::max(0.0, std::floor(lo))), std::min(e.height, uint32_t(std::ceil(hi)))};
}
double WireCoverageMae(const EdgeData& d, const RgbaImage& image) {
  const WireRows w = WireRowsOf(d.edges);
  RgbaImage rows;
  rows.width = image.width;
  rows.height = w.y1 - w.y0;
  const size_t row_bytes = size_t{image.width} * 4;
  rows.pixels.assign(image.pixels.begin() + w.y0 * row_bytes,
                     image.pixels.begin() + w.y1 * row_bytes);
  const std::vector<float> coverage(d.edges.coverage.begin() + size_t{w.y0} * image.width,
                                    d.edges.coverage.begin() + size_t{w.y1} * image.width);
  absl::StatusOr<CoverageError> c = MeasureCoverage(rows, coverage);
  EXPECT_TRUE(c.ok()) << c.status();
  return c.ok() ? c->edge_mae : std::nan("");
}

// Edge PSNR over the edge mask less the wire rows: the half-planes' edges alone.
double EdgePsnrOffWires(const EdgeData& d, const RgbaImage& image) {
  const WireRows w = WireRowsOf(d.edges);
  std::vector<uint8_t> mask = d.edge_mask;
  std::fill(mask.begin() + ptrdiff_t{w.y0} * image.width,
            mask.begin() + ptrdiff_t{w.y1} * image.width, uint8_t{0});
  absl::StatusOr<double> p = PsnrMasked(image, d.reference, mask);
  EXPECT_TRUE(p.ok()) << p.status();
  return p.ok() ? *p : std::nan("");
}

// vis_mlaa_coverage analytic: one sample rasterized, the others found by testing each sample
// position against the triangles the 3x3 pixels around it show and the triangles next to those.
// It anti-aliases the half-planes' edges as raster does and leaves the other pixels alone
// (lavapipe, edge PSNR: 16.30 dB against raster's and msaa's 17.97, none 8.18; off the wire rows
// 17.99 against 18.00). What it loses: the wires that pass between the pixel centres, which no
// pixel nearby shows.
TEST(AaTest, VisMlaaAnalyticCoverage) {
  const EdgeData* d = SharedEdges();
  ASSERT_NE(d, nullptr) << "edge scene set-up failed (see the first failure)";
  Renderer& r = SharedRenderer();
  if (!r.device_info().visibility_buffer) GTEST_SKIP() << "no visibility buffer on this device";
  Settings s = EdgeSettings(d->edges, AaMode::kVisMlaa, 4);
  s.vis_mlaa_coverage = VisMlaaCoverage::kRaster;
  absl::StatusOr<Frame> raster = RenderEdges(*d, s);
  ASSERT_TRUE(raster.ok()) << raster.status();
  s.vis_mlaa_coverage = VisMlaaCoverage::kAnalytic;
  absl::StatusOr<Frame> vis = RenderEdges(*d, s);
  ASSERT_TRUE(vis.ok()) << vis.status();
  ASSERT_EQ(vis->settings.effective.aa, AaMode::kVisMlaa) << Notes(*vis);
  EXPECT_EQ(vis->settings.effective.vis_mlaa_coverage, VisMlaaCoverage::kAnalytic);
  const double psnr = EdgePsnr(*d, vis->image);
  const double mae = CoverageMae(*d, vis->image);
  absl::StatusOr<double> rest = PsnrMasked(vis->image, d->none, InvertMask(d->edge_mask));
  ASSERT_TRUE(rest.ok()) << rest.status();
  const double raster_psnr = EdgePsnr(*d, raster->image);
  const double raster_mae = CoverageMae(*d, raster->image);
  const double planes = EdgePsnrOffWires(*d, vis->image);
  const double raster_planes = EdgePsnrOffWires(*d, raster->image);
  std::printf("vis_mlaa analytic: edge PSNR %.2f dB (raster %.2f, none %.2f), off the wire rows "
              "%.2f (raster %.2f), coverage MAE %.4f (raster %.4f, none %.4f), %llu edge pixels; "
              "off the edges %.2f dB from none\n",
              psnr, raster_psnr, d->none_edge_psnr, planes, raster_planes, mae, raster_mae,
              d->none_coverage_mae, static_cast<unsigned long long>(vis->stats.edge_pixels),
              *rest);
  EXPECT_GE(psnr, d->none_edge_psnr + 4.0) << "analytic coverage does not anti-alias";
  EXPECT_GE(psnr, raster_psnr - 2.0) << "analytic coverage far below raster's";
  EXPECT_GE(planes, raster_planes - 0.5) << "analytic coverage below raster's off the wires";
  EXPECT_LT(mae, d->none_coverage_mae) << "analytic coverage MAE " << mae;
  EXPECT_LE(mae, 1.2 * raster_mae) << "analytic coverage MAE " << mae << ", raster " << raster_mae;
  EXPECT_GE(*rest, 50.0) << "analytic coverage changed pixels away from the edges";
  EXPECT_GT(vis->stats.edge_pixels, 0u);
  ExpectNoValidationMessages(r);
}

// vis_mlaa's runner-up surfaces: a wire thinner than a pixel loses the vote in many of its
// pixels, and the neighbours geometric AA borrows from (across the wire) do not show it; where
// no neighbour shows it, it is shaded as well, down to one sample of the four, and takes its
// share of the pixel. So the wires keep their coverage, as with msaa at the same samples, and
// the edges score as msaa's (the target: within 0.5 dB). Raster coverage: it sees every
// sample, where analytic misses the wires no pixel centre nearby shows (see above).
TEST(AaTest, VisMlaaRunnerUpSurfaces) {
  Renderer& r = SharedRenderer();
  TESSERA_SKIP_WITHOUT_VISIBILITY_BUFFER(r);
  const EdgeData* d = SharedEdges();
  ASSERT_NE(d, nullptr) << "edge scene set-up failed (see the first failure)";
  const EdgeScene& e = d->edges;
  Settings s = EdgeSettings(e, AaMode::kVisMlaa, 4);
  s.vis_mlaa_coverage = VisMlaaCoverage::kRaster;
  absl::StatusOr<Frame> vis = RenderEdges(*d, s);
  absl::StatusOr<Frame> msaa = RenderEdges(*d, EdgeSettings(e, AaMode::kMsaa, 4));
  ASSERT_TRUE(vis.ok()) << vis.status();
  ASSERT_TRUE(msaa.ok()) << msaa.status();
  ASSERT_EQ(vis->settings.effective.samples, msaa->settings.effective.samples);
  const double none_mae = WireCoverageMae(*d, d->none);
  const double msaa_mae = WireCoverageMae(*d, msaa->image);
  const double vis_mae = WireCoverageMae(*d, vis->image);
  // How much of the error without AA vis_mlaa removes on the wires, against msaa's 4 samples:
  // 1.00 on lavapipe (the same pixels as msaa's); 0.88 when only runner-ups holding 3/8 of the
  // samples were shaded, 0.79 without the runner-ups (each wire then missing from the pixels
  // where it lost the vote).
  const double closed = (none_mae - vis_mae) / (none_mae - msaa_mae);
  const double vis_psnr = EdgePsnr(*d, vis->image), msaa_psnr = EdgePsnr(*d, msaa->image);
  std::printf(
      "wire rows coverage MAE: none %.4f, msaa %.4f, vis_mlaa %.4f (%.2f of msaa's gain); "
      "%llu edge pixels, %llu runner-ups shaded; edge PSNR vis_mlaa %.2f dB, msaa %.2f\n",
      none_mae, msaa_mae, vis_mae, closed, static_cast<unsigned long long>(vis->stats.edge_pixels),
      static_cast<unsigned long long>(vis->stats.runner_up_pixels), vis_psnr, msaa_psnr);
  EXPECT_GT(vis->stats.runner_up_pixels, 0u);
  EXPECT_GE(closed, 0.97) << "vis_mlaa's wires: coverage MAE " << vis_mae << ", msaa " << msaa_mae
                          << ", none " << none_mae;
  EXPECT_GE(vis_psnr, msaa_psnr - 0.5) << "vis_mlaa's edges against msaa's at the same samples";
  ExpectNoValidationMessages(r);
}

// TAA with a still camera accumulates its jittered frames towards the supersampled picture;
// each view id has its own history, and a new one starts without any.
TEST(AaTest, TaaStillCameraConverges) {
  const EdgeData* d = SharedEdges();
  ASSERT_NE(d, nullptr) << "edge scene set-up failed (see the first failure)";
  Renderer& r = SharedRenderer();
  constexpr uint64_t kView = 0x7aa0001, kFreshView = 0x7aa0002;
  constexpr int kFrames = 24;
  const Settings s = EdgeSettings(d->edges, AaMode::kTaa);
  std::vector<double> psnr;
  RgbaImage first;
  for (int i = 0; i < kFrames; ++i) {
    absl::StatusOr<Frame> f = RenderEdges(*d, s, kView);
    ASSERT_TRUE(f.ok()) << "frame " << i + 1 << ": " << f.status();
    psnr.push_back(EdgePsnr(*d, f->image));
    if (i == 0) first = std::move(f->image);
  }
  std::printf("taa edge PSNR by frame (none %.2f dB):", d->none_edge_psnr);
  for (int i : {1, 2, 4, 8, 16, 24}) std::printf(" %d: %.2f", i, psnr[size_t(i - 1)]);
  std::printf("\n");
  EXPECT_GE(psnr.back(), d->none_edge_psnr + 4.0)
      << "frame " << kFrames << " " << psnr.back() << " dB, none " << d->none_edge_psnr;
  EXPECT_GT(psnr.back(), psnr.front()) << "frame 1 " << psnr.front() << " dB";
  EXPECT_NEAR(psnr.front(), d->none_edge_psnr, 3.0) << "frame 1 is one jittered frame";

  // Another view id: no history, so its first frame is the first frame above (the same jitter).
  absl::StatusOr<Frame> fresh = RenderEdges(*d, s, kFreshView);
  ASSERT_TRUE(fresh.ok()) << fresh.status();
  const double fresh_psnr = EdgePsnr(*d, fresh->image);
  std::printf("taa new view, first frame: %.2f dB\n", fresh_psnr);
  EXPECT_NEAR(fresh_psnr, d->none_edge_psnr, 3.0) << "a new view started from another's history";
  EXPECT_EQ(fresh->image.pixels, first.pixels) << "a new view's first frame differs";

  // The other view's frame left this view's history alone.
  absl::StatusOr<Frame> again = RenderEdges(*d, s, kView);
  ASSERT_TRUE(again.ok()) << again.status();
  const double again_psnr = EdgePsnr(*d, again->image);
  std::printf("taa first view again: %.2f dB\n", again_psnr);
  EXPECT_GE(again_psnr, d->none_edge_psnr + 4.0) << "the first view lost its history";
  ExpectNoValidationMessages(r);
}

// TAA while the camera moves: each frame blends a tenth or more of the new frame into the
// reprojected history (clipped, where the camera moved, to the neighbourhood's mean +- one
// standard deviation). Before, a moving camera's TAA never blended its history (the blend count
// stayed at 0), so each frame was its own jittered frame: the picture shook by up to half a pixel
// while the camera moved. The demo scene orbited by 0.01 rad a frame for 16 frames, the last frame
// against the same view settled (16 frames of a still camera, the jittered supersample): on
// lavapipe 28.8 dB; 26.2 dB before (the 16th jittered frame alone); 28.0 dB with the history
// clipped to the whole colour box. (The unjittered frame without AA is 32.7 dB from it: what
// blending under motion still costs is resampling blur.)
TEST(AaTest, TaaBlendsHistoryWhileTheCameraMoves) {
  Renderer& r = SharedRenderer();
  const SceneHandle& scene = SharedDemoScene();
  const Camera start = FromSceneCamera(scene->info().cameras[0]);
  const glm::mat4 world = glm::inverse(ViewMatrix(start));
  const glm::vec3 eye(world[3]), target = eye - 5.0f * glm::vec3(world[2]);
  auto orbit = [&](int k) {  // about the point 5 units ahead
    Camera c = start;
    c.view.reset();
    c.scene_camera = -1;
    const float a = 0.01f * float(k);
    const glm::vec3 d = eye - target;
    c.eye = target + glm::vec3(std::cos(a) * d.x - std::sin(a) * d.z, d.y,
                               std::sin(a) * d.x + std::cos(a) * d.z);
    c.target = target;
    return c;
  };
  Settings s;
  s.width = 320;
  s.height = 240;
  s.aa = AaMode::kTaa;
  constexpr int kFrames = 16;
  constexpr uint64_t kMoving = 0x7aa0010, kSettled = 0x7aa0011, kNone = 0x7aa0012;
  FrameCapture moving, settled, unaliased;
  for (int k = 0; k < kFrames; ++k)
    ASSERT_TRUE(r.Render(*scene, orbit(k), s, kMoving, k + 1 == kFrames ? &moving : nullptr).ok());
  for (int k = 0; k < kFrames; ++k)
    ASSERT_TRUE(
        r.Render(*scene, orbit(kFrames - 1), s, kSettled, k + 1 == kFrames ? &settled : nullptr)
            .ok());
  // The same view without anti-aliasing.
  Settings none = s;
  none.aa = AaMode::kNone;
  ASSERT_TRUE(r.Render(*scene, orbit(kFrames - 1), none, kNone, &unaliased).ok());
  for (uint64_t v : {kMoving, kSettled}) r.ForgetView(*scene, v);
  const double blended = HdrPsnr(moving.hdr, settled.hdr);
  const double unaliased_db = HdrPsnr(unaliased.hdr, settled.hdr);
  std::printf("orbiting TAA against the settled view: %.2f dB; no AA %.2f dB\n", blended,
              unaliased_db);
  // Against the same device's frame without AA, not a fixed figure: an NVIDIA H200 measured
  // both about 1 dB below lavapipe (27.34 and 31.62 dB), and failed the fixed bound tuned here
  // (27.5). Not blending was 6.5 dB below the frame without AA on lavapipe; blending is 3.8 dB
  // below it here and 4.3 on the H200.
  EXPECT_GE(blended, unaliased_db - 5.0) << "TAA did not blend the moving camera's history";
  ExpectNoValidationMessages(r);
}

// vis_mlaa on a lit scene (metals, a textured, a normal-mapped, an alpha-masked and a blended
// object) against its golden; the shading is the same BRDF as without AA, so the frames differ
// on the edges only.
// vis_mlaa 4x on the demo scene at 256x192, its samples found as `coverage` says.
Settings DemoVisMlaa(VisMlaaCoverage coverage) {
  Settings s;
  s.width = 256;
  s.height = 192;
  s.aa = AaMode::kVisMlaa;
  s.samples = 4;
  s.vis_mlaa_coverage = coverage;
  return s;
}

TEST(AaTest, VisMlaaGolden) {
  Renderer& r = SharedRenderer();
  TESSERA_SKIP_WITHOUT_VISIBILITY_BUFFER(r);
  const SceneHandle& scene = SharedDemoScene();
  const Camera camera = FromSceneCamera(scene->info().cameras[0]);
  // Both ways of finding the samples: raster against the golden, analytic against raster (the
  // demo's sky and its alpha-masked object exercise the resolve's sky and cut-out rules).
  RgbaImage raster;
  uint64_t raster_edges = 0;
  for (VisMlaaCoverage coverage : {VisMlaaCoverage::kRaster, VisMlaaCoverage::kAnalytic}) {
    SCOPED_TRACE(ToString(coverage));
    Settings s = DemoVisMlaa(coverage);
    FrameCapture capture;
    absl::StatusOr<Frame> vis = r.Render(*scene, camera, s, &capture);
    ASSERT_TRUE(vis.ok()) << vis.status();
    ASSERT_EQ(vis->settings.effective.aa, AaMode::kVisMlaa) << Notes(*vis);
    EXPECT_EQ(vis->settings.effective.vis_mlaa_coverage, coverage);
    EXPECT_FALSE(HasNote(*vis, "aa")) << Notes(*vis);
    // The resolve counted each pixel's surface (and each runner-up shaded) in the material list
    // the classification appended it to, and every pixel is in one list, or shows the sky,
    // which the classification wrote. Where the shading is one dispatch (no lists), the
    // surfaces it counted and the sky's pixels make the frame.
    EXPECT_GT(capture.background_pixels, 0u);  // the demo's view has sky
    if (r.device_info().shade_all_materials) {
      EXPECT_TRUE(capture.shade_lists.empty());
      EXPECT_GE(vis->stats.shaded_pixels + capture.background_pixels, uint64_t(s.width) * s.height);
      EXPECT_LE(vis->stats.shaded_pixels + capture.background_pixels,
                uint64_t(s.width) * s.height + vis->stats.runner_up_pixels);
    } else {
      ASSERT_FALSE(capture.shade_lists.empty());
      uint64_t listed = 0;
      for (size_t m = 0; m < capture.shade_lists.size(); ++m) {
        EXPECT_EQ(capture.shade_lists[m].x, capture.shade_lists[m].y) << "material " << m;
        listed += capture.shade_lists[m].y;
      }
      EXPECT_EQ(listed + capture.background_pixels,
                uint64_t(s.width) * s.height + vis->stats.runner_up_pixels)
          << vis->stats.runner_up_pixels << " runner-ups, " << capture.background_pixels
          << " sky pixels";
    }
    s.aa = AaMode::kNone;
    absl::StatusOr<Frame> none = r.Render(*scene, camera, s);
    ASSERT_TRUE(none.ok()) << none.status();
    absl::StatusOr<double> psnr = Psnr(vis->image, none->image);
    ASSERT_TRUE(psnr.ok()) << psnr.status();
    std::printf("demo 256x192, %s: vis_mlaa vs none %.2f dB\n", ToString(coverage).data(), *psnr);
    EXPECT_GE(*psnr, 30.0) << "vis_mlaa shades differently from aa none";
    ExpectNoValidationMessages(r);
    std::printf("demo 256x192, %s: %llu edge pixels\n", ToString(coverage).data(),
                static_cast<unsigned long long>(vis->stats.edge_pixels));
    if (coverage == VisMlaaCoverage::kRaster) {
      CompareWithGolden("vis_mlaa_demo", vis->image);
      raster = vis->image;
      raster_edges = vis->stats.edge_pixels;
      continue;
    }
    // analytic against raster: the same but along the silhouettes of the finely tessellated
    // spheres, whose grazing triangles no pixel centre shows and which lie more edges away
    // from those shown than the resolve follows (lavapipe: 35.5 dB; without the adjacency
    // 29.5).
    absl::StatusOr<double> against = Psnr(vis->image, raster);
    ASSERT_TRUE(against.ok()) << against.status();
    std::printf("demo 256x192: analytic vs raster %.2f dB\n", *against);
    EXPECT_GE(*against, 34.0) << "analytic coverage strays from raster";
    // Its edge list holds the pixels near another surface, not every pixel near a boundary
    // between one mesh's triangles (lavapipe: 5483 against raster's 7752, whose list has the
    // pixels whose samples fall on two triangles; 14384 when such pixels were listed too).
    EXPECT_LE(vis->stats.edge_pixels, raster_edges)
        << "analytic lists the pixels inside a surface as edges";
  }
}

// The resolve lists its edge pixels with more than one surface again, in its blend list, and the
// runner-ups' steps and geometric AA run over that list only: the edge pixels whose samples fall
// on triangles of one surface (the demo spheres' tessellation) own every sample and pass through.
// The blend list must hold exactly the pixels the aa_mask view shows darker than white (whose
// surface does not own every sample): one left out keeps its aliased edge, one too many costs.
// The demo scene with its glass made opaque: the blended surfaces are drawn over the mask.
TEST(AaTest, VisMlaaBlendsOnlyPixelsWithTwoSurfaces) {
  Renderer& r = SharedRenderer();
  TESSERA_SKIP_WITHOUT_VISIBILITY_BUFFER(r);
  CpuScene demo = BuildDemoScene();
  for (Material& m : demo.materials)
    if (m.alpha_mode == AlphaMode::kBlend) m.alpha_mode = AlphaMode::kOpaque;
  absl::StatusOr<SceneHandle> scene = r.LoadScene(std::move(demo));
  ASSERT_TRUE(scene.ok()) << scene.status();
  const Camera camera = FromSceneCamera((*scene)->info().cameras[0]);
  for (VisMlaaCoverage coverage : {VisMlaaCoverage::kRaster, VisMlaaCoverage::kAnalytic}) {
    SCOPED_TRACE(ToString(coverage));
    Settings s = DemoVisMlaa(coverage);
    s.debug_view = DebugView::kAaMask;
    absl::StatusOr<Frame> f = r.Render(**scene, camera, s);
    ASSERT_TRUE(f.ok()) << f.status();
    ASSERT_EQ(f->settings.effective.debug_view, DebugView::kAaMask) << Notes(*f);
    uint64_t darker = 0;
    for (size_t i = 0; i < f->image.pixels.size(); i += 4) {
      const uint8_t* p = &f->image.pixels[i];
      darker += std::min({p[0], p[1], p[2]}) < 255 ? 1 : 0;
    }
    std::printf("demo 256x192, %s: %llu edge pixels, %llu blended, %llu not white in aa_mask\n",
                ToString(coverage).data(), static_cast<unsigned long long>(f->stats.edge_pixels),
                static_cast<unsigned long long>(f->stats.blend_pixels),
                static_cast<unsigned long long>(darker));
    EXPECT_GT(f->stats.blend_pixels, 0u);
    EXPECT_EQ(f->stats.blend_pixels, darker);
    if (coverage == VisMlaaCoverage::kRaster) {
      EXPECT_LT(f->stats.blend_pixels, f->stats.edge_pixels)
          << "every edge pixel is blended, the ones inside a surface too";
    } else {
      EXPECT_LE(f->stats.blend_pixels, f->stats.edge_pixels);
    }
    ExpectNoValidationMessages(r);
  }
}

// TAA and vis_mlaa's geometric AA run as fragment or compute shaders (post_stage): the same
// pixels either way (the tonemap's input, captured: the tonemap's own sRGB rounding differs
// between the stages, see lighting_test.cpp), for both pipelines, and the aa_mask view too.
TEST(AaTest, PostStagesGiveTheSamePixels) {
  Renderer& r = SharedRenderer();
  const SceneHandle& scene = SharedDemoScene();
  const Camera camera = FromSceneCamera(scene->info().cameras[0]);
  struct Case {
    AaMode aa;
    Pipeline pipeline;
    DebugView view;
  };
  uint64_t view = 4200;
  for (const Case& c : {Case{AaMode::kTaa, Pipeline::kForward, DebugView::kNone},
                        Case{AaMode::kTaa, Pipeline::kVisibility, DebugView::kNone},
                        Case{AaMode::kVisMlaa, Pipeline::kAuto, DebugView::kNone},
                        Case{AaMode::kVisMlaa, Pipeline::kAuto, DebugView::kAaMask}}) {
    Settings s;
    s.width = 200;
    s.height = 120;
    s.aa = c.aa;
    s.pipeline = c.pipeline;
    s.debug_view = c.view;
    std::vector<float> hdr[2];
    for (int i = 0; i < 2; ++i) {
      s.post_stage = i == 0 ? PostStage::kFragment : PostStage::kCompute;
      // Two frames of a fresh view each, so TAA blends a real history.
      absl::StatusOr<Frame> f = r.Render(*scene, camera, s, ++view);
      ASSERT_TRUE(f.ok()) << f.status();
      FrameCapture capture;
      f = r.Render(*scene, camera, s, view, &capture);
      ASSERT_TRUE(f.ok()) << f.status();
      EXPECT_EQ(f->settings.effective.post_stage, s.post_stage);
      hdr[i] = std::move(capture.hdr);
    }
    ASSERT_FALSE(hdr[0].empty());
    EXPECT_EQ(hdr[0], hdr[1]) << ToString(c.aa) << " " << ToString(c.pipeline) << " "
                              << ToString(c.view);
  }
  ExpectNoValidationMessages(r);
}

// The aa_mask debug view: white where one surface owns every sample, darker on the edges; it
// exists for vis_mlaa only, and asking for it otherwise is reported and renders normally.
TEST(AaTest, AaMaskDebugView) {
  const EdgeData* d = SharedEdges();
  ASSERT_NE(d, nullptr) << "edge scene set-up failed (see the first failure)";
  Renderer& r = SharedRenderer();
  TESSERA_SKIP_WITHOUT_VISIBILITY_BUFFER(r);
  const EdgeScene& e = d->edges;
  absl::StatusOr<Frame> f =
      RenderEdges(*d, EdgeSettings(e, AaMode::kVisMlaa, 4, DebugView::kAaMask));
  ASSERT_TRUE(f.ok()) << f.status();
  ASSERT_EQ(f->settings.effective.debug_view, DebugView::kAaMask) << Notes(*f);
  ASSERT_EQ(f->image.width, e.width);
  ASSERT_EQ(f->image.height, e.height);

  auto coverage = [&](uint32_t x, uint32_t y) { return e.coverage[size_t(y) * e.width + x]; };
  auto darkest = [&](uint32_t x, uint32_t y) {
    const uint8_t* p = &f->image.pixels[(size_t(y) * e.width + x) * 4];
    return std::min({p[0], p[1], p[2]});
  };
  uint64_t interior = 0, interior_not_white = 0, edge = 0, edge_darker = 0;
  uint64_t half = 0, half_darker = 0;  // coverage 0.4..0.6: every 4-sample pattern is split
  std::string first_bad;
  for (uint32_t y = 1; y + 1 < e.height; ++y) {
    for (uint32_t x = 1; x + 1 < e.width; ++x) {
      const float c = coverage(x, y);
      if (c == 0.0f || c == 1.0f) {
        bool same = true;
        for (int dy = -1; dy <= 1; ++dy)
          for (int dx = -1; dx <= 1; ++dx)
            same = same && coverage(uint32_t(int(x) + dx), uint32_t(int(y) + dy)) == c;
        if (!same) continue;
        ++interior;
        if (darkest(x, y) != 255) {
          if (interior_not_white == 0)
            first_bad = "(" + std::to_string(x) + ", " + std::to_string(y) +
                        ") = " + std::to_string(darkest(x, y));
          ++interior_not_white;
        }
      } else {
        ++edge;
        edge_darker += darkest(x, y) < 255 ? 1 : 0;
        if (c >= 0.4f && c <= 0.6f) {
          ++half;
          half_darker += darkest(x, y) < 255 ? 1 : 0;
        }
      }
    }
  }
  std::printf(
      "aa_mask: %llu interior pixels, %llu not white; %llu edge pixels, %llu darker; "
      "%llu at coverage 0.4-0.6, %llu darker\n",
      static_cast<unsigned long long>(interior),
      static_cast<unsigned long long>(interior_not_white), static_cast<unsigned long long>(edge),
      static_cast<unsigned long long>(edge_darker), static_cast<unsigned long long>(half),
      static_cast<unsigned long long>(half_darker));
  ASSERT_GT(interior, 0u);
  EXPECT_EQ(interior_not_white, 0u) << "interior pixels are not white, first " << first_bad;
  EXPECT_GT(edge_darker, 0u) << "no edge pixel shows partial coverage";
  // An edge through the middle of a pixel splits its samples between two surfaces (a sample
  // exactly on an edge may go either way, hence not all).
  ASSERT_GT(half, 0u);
  EXPECT_GE(double(half_darker), 0.95 * double(half)) << half_darker << " of " << half;

  // Without vis_mlaa there is no mask: a note, and the frame aa none would give anyway.
  absl::StatusOr<Frame> asked =
      r.Render(*d->scene, d->camera, EdgeSettings(e, AaMode::kNone, 4, DebugView::kAaMask));
  absl::StatusOr<Frame> plain =
      r.Render(*d->scene, d->camera, EdgeSettings(e, AaMode::kNone, 4, DebugView::kNone));
  ASSERT_TRUE(asked.ok()) << asked.status();
  ASSERT_TRUE(plain.ok()) << plain.status();
  EXPECT_TRUE(HasNote(*asked, "debug_view")) << Notes(*asked);
  EXPECT_EQ(asked->settings.effective.debug_view, DebugView::kNone);
  EXPECT_EQ(asked->image.pixels, plain->image.pixels)
      << "aa_mask without vis_mlaa changed the frame";
  ExpectNoValidationMessages(r);
}

// A texture seam: one mesh whose two triangles meet along a slanted edge with the same positions
// and normals on both sides but other texture coordinates (split vertices), each side mapped to
// one half of a white and black texture. The sides shade apart, as two surfaces do, so vis_mlaa
// must anti-alias the seam as msaa does; taken as one surface (the grouping before 2026-11-28
// looked at positions and normals only) the seam was shaded once per pixel and stayed as aliased
// as without AA. Split vertices that are no seam stay one surface (the aa_mask view white
// everywhere): the same coordinates; coordinates a whole unit apart under a REPEAT texture (a
// sphere's u = 0 and u = 1); and other coordinates in a set no texture of the material reads.
enum class Split { kSeam, kSameUv, kWholeUnitApart, kUnreadSet };
CpuScene SeamScene(Split split) {
  CpuScene s;
  s.name = "split vertices";
  // Larger than the view (so the seam is the only edge); the diagonal rises 1 in 2.5.
  const glm::vec3 p[4] = {{-5, -2, 0}, {5, -2, 0}, {5, 2, 0}, {-5, 2, 0}};
  // Well inside the texture's halves (textures may be resampled to a bucket's size).
  const glm::vec2 white(0.125f, 0.5f), black(0.875f, 0.5f);
  glm::vec2 other_uv0 = white, other_uv1(0.0f);
  if (split == Split::kSeam) other_uv0 = black;
  if (split == Split::kWholeUnitApart) other_uv0 = white + glm::vec2(1.0f, -2.0f);
  if (split == Split::kUnreadSet) other_uv1 = glm::vec2(0.5f, 0.25f);
  auto vertex = [](const glm::vec3& position, const glm::vec2& uv0, const glm::vec2& uv1) {
    Vertex v;
    v.position = position;
    v.normal = glm::vec3(0, 0, 1);
    v.uv0 = uv0;
    v.uv1 = uv1;
    return v;
  };
  const glm::vec2 none(0.0f);
  s.vertices = {vertex(p[0], white, none),          vertex(p[1], white, none),
                vertex(p[2], white, none),          vertex(p[0], other_uv0, other_uv1),
                vertex(p[2], other_uv0, other_uv1), vertex(p[3], other_uv0, other_uv1)};
  s.indices = {0, 1, 2, 3, 4, 5};  // counter-clockwise seen from +z
  Primitive prim;
  prim.index_count = 6;
  prim.vertex_count = 6;
  prim.bounds = {glm::vec3(-5, -2, 0), glm::vec3(5, 2, 0)};
  s.primitives.push_back(prim);
  s.meshes.push_back({"seam", {0}});
  auto image = std::make_shared<Image>();
  image->name = "white | black";
  image->width = image->height = 16;
  for (uint32_t y = 0; y < 16; ++y)
    for (uint32_t x = 0; x < 16; ++x) {
      const uint8_t v = x < 8 ? 255 : 0;
      image->rgba8.insert(image->rgba8.end(), {v, v, v, 255});
    }
  const WrapMode wrap =
      split == Split::kWholeUnitApart ? WrapMode::kRepeat : WrapMode::kClampToEdge;
  s.textures.push_back(Texture{image, true, wrap, wrap});
  Material m;
  m.base_color.texture = 0;  // TEXCOORD_0
  s.materials.push_back(m);
  Drawable d;
  d.world_bounds = prim.bounds;
  s.drawables.push_back(d);
  s.bounds = prim.bounds;
  CountGeneratedScene(s);
  return s;
}

TEST(AaTest, VisMlaaAntiAliasesTextureSeams) {
  Renderer& r = SharedRenderer();
  TESSERA_SKIP_WITHOUT_VISIBILITY_BUFFER(r);
  Camera camera;
  camera.eye = glm::vec3(0.0f, 0.0f, 2.0f);
  camera.target = glm::vec3(0.0f);
  auto settings = [](AaMode aa, VisMlaaCoverage coverage = VisMlaaCoverage::kAuto,
                     DebugView view = DebugView::kBaseColor) {
    Settings s;
    s.width = 160;
    s.height = 96;
    s.aa = aa;
    s.samples = 4;
    s.vis_mlaa_coverage = coverage;
    s.debug_view = view;
    return s;
  };
  // Pixels neither white nor black (8-bit sRGB, red channel): the seam's blends.
  auto blended = [](const RgbaImage& image) {
    uint64_t n = 0;
    for (size_t i = 0; i < image.pixels.size(); i += 4)
      n += image.pixels[i] > 8 && image.pixels[i] < 247 ? 1 : 0;
    return n;
  };
  auto not_white = [](const RgbaImage& image) {
    uint64_t n = 0;
    for (size_t i = 0; i < image.pixels.size(); i += 4) n += image.pixels[i] != 255 ? 1 : 0;
    return n;
  };
  const VisMlaaCoverage kCoverages[] = {VisMlaaCoverage::kRaster, VisMlaaCoverage::kAnalytic};

  absl::StatusOr<SceneHandle> seam = r.LoadScene(SeamScene(Split::kSeam));
  ASSERT_TRUE(seam.ok()) << seam.status();
  absl::StatusOr<Frame> none = r.Render(**seam, camera, settings(AaMode::kNone));
  absl::StatusOr<Frame> msaa = r.Render(**seam, camera, settings(AaMode::kMsaa));
  ASSERT_TRUE(none.ok()) << none.status();
  ASSERT_TRUE(msaa.ok()) << msaa.status();
  EXPECT_EQ(blended(none->image), 0u) << "without AA the seam is white against black";
  // The seam crosses the frame, msaa blending most of the pixels along it.
  ASSERT_GE(blended(msaa->image), 100u) << "msaa did not blend the seam";
  // Scored over the seam: the pixels msaa changed.
  absl::StatusOr<std::vector<uint8_t>> seam_pixels = DifferenceMask(msaa->image, none->image);
  ASSERT_TRUE(seam_pixels.ok()) << seam_pixels.status();
  const absl::StatusOr<double> none_db = PsnrMasked(none->image, msaa->image, *seam_pixels);
  ASSERT_TRUE(none_db.ok()) << none_db.status();
  for (VisMlaaCoverage coverage : kCoverages) {
    SCOPED_TRACE(ToString(coverage));
    absl::StatusOr<Frame> vis = r.Render(**seam, camera, settings(AaMode::kVisMlaa, coverage));
    ASSERT_TRUE(vis.ok()) << vis.status();
    ASSERT_EQ(vis->settings.effective.aa, AaMode::kVisMlaa) << Notes(*vis);
    const absl::StatusOr<double> db = PsnrMasked(vis->image, msaa->image, *seam_pixels);
    ASSERT_TRUE(db.ok()) << db.status();
    std::printf("texture seam, %s: vis_mlaa vs msaa over the seam %.2f dB (none %.2f); blended "
                "pixels %llu (msaa %llu), %llu edge pixels\n",
                ToString(coverage).data(), *db, *none_db,
                static_cast<unsigned long long>(blended(vis->image)),
                static_cast<unsigned long long>(blended(msaa->image)),
                static_cast<unsigned long long>(vis->stats.edge_pixels));
    EXPECT_GE(*db, 35.0) << "vis_mlaa's seam is not msaa's";
    EXPECT_GE(double(blended(vis->image)), 0.9 * double(blended(msaa->image)));
    // The aa_mask view shows the seam's pixels owning part of their samples.
    absl::StatusOr<Frame> mask =
        r.Render(**seam, camera, settings(AaMode::kVisMlaa, coverage, DebugView::kAaMask));
    ASSERT_TRUE(mask.ok()) << mask.status();
    EXPECT_GE(not_white(mask->image), 100u) << "the seam's pixels own all their samples";
  }

  for (Split split : {Split::kSameUv, Split::kWholeUnitApart, Split::kUnreadSet}) {
    absl::StatusOr<SceneHandle> one = r.LoadScene(SeamScene(split));
    ASSERT_TRUE(one.ok()) << one.status();
    for (VisMlaaCoverage coverage : kCoverages) {
      absl::StatusOr<Frame> mask =
          r.Render(**one, camera, settings(AaMode::kVisMlaa, coverage, DebugView::kAaMask));
      ASSERT_TRUE(mask.ok()) << mask.status();
      ASSERT_EQ(mask->settings.effective.debug_view, DebugView::kAaMask) << Notes(*mask);
      EXPECT_EQ(not_white(mask->image), 0u)
          << "split vertices without a seam taken as two surfaces: split " << int(split) << ", "
          << ToString(coverage);
    }
  }
  ExpectNoValidationMessages(r);
}

// Past 4095 drawables the visibility id gives the drawable more bits: a city whose visible
// buildings have indices beyond 4095 renders in vis_mlaa (no fallback) and matches the frame
// without AA away from the edges. A wrapped id would shade another building's surface.
TEST(AaTest, ManyDrawables) {
  Renderer& r = SharedRenderer();
  TESSERA_SKIP_WITHOUT_VISIBILITY_BUFFER(r);
  CityParams params;
  params.blocks_x = 7;
  params.blocks_z = 7;
  params.buildings_per_side = 10;
  params.facade_detail = 1;
  const CpuScene city = BuildCityScene(params);
  ASSERT_GT(city.drawables.size(), 4095u);
  const auto cam = std::find_if(city.cameras.begin(), city.cameras.end(),
                                [](const SceneCamera& c) { return c.name == "street"; });
  ASSERT_NE(cam, city.cameras.end()) << "no street camera";
  absl::StatusOr<SceneHandle> scene = r.LoadScene(city);
  ASSERT_TRUE(scene.ok()) << scene.status();
  const Camera camera = FromSceneCamera(*cam);
  Settings s;
  s.width = 160;
  s.height = 120;
  s.aa = AaMode::kNone;
  FrameCapture capture;
  capture.want_ids = true;
  absl::StatusOr<Frame> none = r.Render(**scene, camera, s, /*view=*/0, &capture);
  ASSERT_TRUE(none.ok()) << none.status();
  // The view must show drawables whose id + 1 does not fit 12 bits, or it tests nothing.
  const uint64_t wide = uint64_t(std::count_if(capture.ids.begin(), capture.ids.end(),
                                               [](uint32_t id) { return id > 4095u; }));
  EXPECT_GT(wide, 0u) << "no pixel shows a drawable past index 4094";

  s.aa = AaMode::kVisMlaa;
  s.samples = 4;
  absl::StatusOr<Frame> vis = r.Render(**scene, camera, s);
  ASSERT_TRUE(vis.ok()) << vis.status();
  EXPECT_FALSE(HasNote(*vis, "aa")) << Notes(*vis);
  EXPECT_EQ(vis->settings.effective.aa, AaMode::kVisMlaa) << Notes(*vis);
  absl::StatusOr<double> psnr = Psnr(vis->image, none->image);
  ASSERT_TRUE(psnr.ok()) << psnr.status();
  std::printf("city: %zu drawables, %llu of %zu pixels past 4094; vis_mlaa vs none %.2f dB\n",
              city.drawables.size(), static_cast<unsigned long long>(wide), capture.ids.size(),
              *psnr);
  EXPECT_GE(*psnr, 25.0) << "vis_mlaa shades other surfaces than aa none";
  ExpectNoValidationMessages(r);
}

// The same inputs give the same pixels in the post-process and resolve modes too.
TEST(AaTest, Determinism) {
  Renderer& r = SharedRenderer();
  const SceneHandle& scene = SharedDemoScene();
  const Camera camera = FromSceneCamera(scene->info().cameras[0]);
  std::vector<AaMode> modes = {AaMode::kFxaa, AaMode::kMsaa};
  if (r.device_info().visibility_buffer) modes.push_back(AaMode::kVisMlaa);
  for (AaMode aa : modes) {
    Settings s;
    s.width = 160;
    s.height = 120;
    s.aa = aa;
    s.samples = 4;
    absl::StatusOr<Frame> a = r.Render(*scene, camera, s);
    absl::StatusOr<Frame> b = r.Render(*scene, camera, s);
    ASSERT_TRUE(a.ok()) << a.status();
    ASSERT_TRUE(b.ok()) << b.status();
    EXPECT_EQ(a->settings.effective.aa, aa) << Notes(*a);
    EXPECT_EQ(a->image.pixels, b->image.pixels) << ToString(aa) << ": two renders differ";
  }
  ExpectNoValidationMessages(r);
}

// Sample counts the device lacks are clamped to one it has, with a note; msaa with one sample
// is raised to a multisampled count and still anti-aliases.
TEST(AaTest, SampleCounts) {
  const EdgeData* d = SharedEdges();
  ASSERT_NE(d, nullptr) << "edge scene set-up failed (see the first failure)";
  Renderer& r = SharedRenderer();
  const uint32_t supported = r.device_info().sample_counts;
  std::vector<AaMode> modes = {AaMode::kMsaa};
  if (r.device_info().visibility_buffer) modes.push_back(AaMode::kVisMlaa);
  for (AaMode aa : modes) {
    for (uint32_t requested : {2u, 8u}) {
      absl::StatusOr<Frame> f = RenderEdges(*d, EdgeSettings(d->edges, aa, requested));
      ASSERT_TRUE(f.ok()) << f.status();
      const uint32_t got = f->settings.effective.samples;
      std::printf("%s samples %u -> %u%s\n", std::string(ToString(aa)).c_str(), requested, got,
                  Notes(*f).c_str());
      EXPECT_NE(got & supported, 0u) << ToString(aa) << " " << requested << " -> " << got
                                     << ", device sample counts 0x" << std::hex << supported;
      EXPECT_GT(got, 1u) << ToString(aa) << " needs a multisampled target";
      EXPECT_EQ(HasNote(*f, "samples"), got != requested)
          << ToString(aa) << " " << requested << " -> " << got << ":" << Notes(*f);
    }
  }
  absl::StatusOr<Frame> one = RenderEdges(*d, EdgeSettings(d->edges, AaMode::kMsaa, 1));
  ASSERT_TRUE(one.ok()) << one.status();
  const double psnr = EdgePsnr(*d, one->image);
  std::printf("msaa samples 1 -> %u: edge PSNR %.2f dB (none %.2f)\n",
              one->settings.effective.samples, psnr, d->none_edge_psnr);
  EXPECT_GT(one->settings.effective.samples, 1u);
  EXPECT_TRUE(HasNote(*one, "samples")) << Notes(*one);
  // 3 dB, not 6: the smallest multisampled count may be 2 on other devices (4 on lavapipe).
  EXPECT_GE(psnr, d->none_edge_psnr + 3.0) << "msaa raised from 1 sample does not anti-alias";
  ExpectNoValidationMessages(r);
}

}  // namespace
}  // namespace tessera
