// Renders a calibration board into a camera with known intrinsics, lens distortion and pose:
// the test scene of issue 38 (every parameter known). Each output pixel is the mean of 2 x 2
// samples; a sample's ray (the lens undone exactly, per camera, once) meets the board plane,
// and the board's printed image (render_board) is read there, bilinearly. Outside the board:
// mid grey. Gaussian noise of `noise_grey` levels.
#pragma once

#include <Eigen/Core>

#include <cmath>
#include <random>
#include <vector>

#include "runtime/boardcal/board_detect.h"
#include "runtime/geometry/camera.h"

namespace mocap::testing {

class BoardRenderer {
 public:
  // px_per_square: the printed image's resolution (the render reads it bilinearly).
  BoardRenderer(const boardcal::BoardSpec& board, int px_per_square = 48) : board_(board) {
    margin_ = px_per_square / 2;
    tex_ = *boardcal::render_board(board, px_per_square, margin_);
    px_per_m_ = px_per_square / board.square_m;
    // Where the board frame's origin is in the printed image: its corner 0 sits at (1, 1)
    // squares (ChArUco) or (1, 1) squares of the (cols + 1) x (rows + 1) chessboard; the y axis
    // of OpenCV's board image may run either way, so it is found from the image itself.
    auto det = boardcal::BoardDetector::create(board);
    const auto obs = det->detect({tex_.gray.data(), tex_.width_px, tex_.height_px, tex_.width_px});
    const auto corners = board.corners_m();
    // Fit u = a + px_per_m x, v = b + sy px_per_m y with sy = +-1.
    double su = 0, sv_pos = 0, sv_neg = 0;
    for (std::size_t i = 0; i < obs.size(); ++i) {
      const auto& c = corners[static_cast<std::size_t>(obs.ids[i])];
      su += obs.px[i].x() - px_per_m_ * c.x();
      sv_pos += obs.px[i].y() - px_per_m_ * c.y();
      sv_neg += obs.px[i].y() + px_per_m_ * c.y();
    }
    const double n = static_cast<double>(obs.size());
    u0_ = su / n;
    // The consistent sign is the one whose residuals are small.
    double e_pos = 0, e_neg = 0;
    for (std::size_t i = 0; i < obs.size(); ++i) {
      const auto& c = corners[static_cast<std::size_t>(obs.ids[i])];
      e_pos += std::abs(obs.px[i].y() - px_per_m_ * c.y() - sv_pos / n);
      e_neg += std::abs(obs.px[i].y() + px_per_m_ * c.y() - sv_neg / n);
    }
    sy_ = e_pos <= e_neg ? 1.0 : -1.0;
    v0_ = (sy_ > 0 ? sv_pos : sv_neg) / n;
    // The pixel centre convention of the detector (corner at a pixel boundary = x.5 - 0.5).
    found_ = obs.size();
  }

  std::size_t corners_found_in_print() const { return found_; }

  // board_to_camera: X_cam = R X_board + t.
  std::vector<std::uint8_t> render(const Camera& cam, const Eigen::Matrix3d& R,
                                   const Eigen::Vector3d& t, double noise_grey,
                                   std::mt19937& rng) const {
    const int w = cam.width_px();
    const int h = cam.height_px();
    const auto& rays = rays_for(cam);
    std::vector<std::uint8_t> out(static_cast<std::size_t>(w) * static_cast<std::size_t>(h));
    const Eigen::Vector3d nrm = R.col(2);
    const double nt = nrm.dot(t);
    const Eigen::Vector3d r0 = R.col(0);
    const Eigen::Vector3d r1 = R.col(1);
    const double r0t = r0.dot(t);
    const double r1t = r1.dot(t);
    std::normal_distribution<double> noise(0.0, noise_grey);
    // Only the board's bounding box (its printed image's corners projected, plus a margin for
    // the lens's curvature) is traced; the rest is the background.
    int x0 = w, y0 = h, x1 = -1, y1 = -1;
    for (double cu : {0.0, 1.0}) {
      for (double cv : {0.0, 1.0}) {
        const Eigen::Vector3d Xb((cu * (tex_.width_px - 1) - u0_) / px_per_m_,
                                 (cv * (tex_.height_px - 1) - v0_) / (sy_ * px_per_m_), 0.0);
        const Eigen::Vector3d Xc = R * Xb + t;
        if (Xc.z() <= 0.01) return std::vector<std::uint8_t>(static_cast<std::size_t>(w) * h, 128);
        const Eigen::Vector2d px = cam.normalized_to_pixel(
            cam.distort_normalized(Eigen::Vector2d(Xc.x() / Xc.z(), Xc.y() / Xc.z())));
        x0 = std::min(x0, static_cast<int>(std::floor(px.x())));
        x1 = std::max(x1, static_cast<int>(std::ceil(px.x())));
        y0 = std::min(y0, static_cast<int>(std::floor(px.y())));
        y1 = std::max(y1, static_cast<int>(std::ceil(px.y())));
      }
    }
    const int mx = (x1 - x0) / 8 + 4, my = (y1 - y0) / 8 + 4;
    x0 = std::max(0, x0 - mx);
    y0 = std::max(0, y0 - my);
    x1 = std::min(w - 1, x1 + mx);
    y1 = std::min(h - 1, y1 + my);
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        double v = 128;
        if (x >= x0 && x <= x1 && y >= y0 && y <= y1) {
          double sum = 0;
          const Eigen::Vector3d* d4 =
              &rays[(static_cast<std::size_t>(y) * static_cast<std::size_t>(w) +
                     static_cast<std::size_t>(x)) *
                    4];
          for (int s = 0; s < 4; ++s) {
            const Eigen::Vector3d& d = d4[s];
            const double nd = nrm.dot(d);
            if (std::abs(nd) < 1e-12 || nt / nd <= 0) {
              sum += 128;
              continue;
            }
            const double k = nt / nd;
            const double bx = k * r0.dot(d) - r0t;
            const double by = k * r1.dot(d) - r1t;
            sum += sample(u0_ + px_per_m_ * bx, v0_ + sy_ * px_per_m_ * by);
          }
          v = sum / 4;
        }
        if (noise_grey > 0) v += noise(rng);
        out[static_cast<std::size_t>(y) * static_cast<std::size_t>(w) +
            static_cast<std::size_t>(x)] =
            static_cast<std::uint8_t>(std::clamp(std::lround(v), 0L, 255L));
      }
    }
    return out;
  }

 private:
  double sample(double u, double v) const {
    const double fu = std::floor(u), fv = std::floor(v);
    const int iu = static_cast<int>(fu), iv = static_cast<int>(fv);
    if (iu < 0 || iv < 0 || iu + 1 >= tex_.width_px || iv + 1 >= tex_.height_px) return 128;
    const double a = u - fu, b = v - fv;
    auto at = [&](int uu, int vv) {
      return static_cast<double>(
          tex_.gray[static_cast<std::size_t>(vv) * static_cast<std::size_t>(tex_.width_px) +
                    static_cast<std::size_t>(uu)]);
    };
    return (1 - b) * ((1 - a) * at(iu, iv) + a * at(iu + 1, iv)) +
           b * ((1 - a) * at(iu, iv + 1) + a * at(iu + 1, iv + 1));
  }

  // Camera-frame ray (z = 1) of each 2 x 2 sub-sample, cached per camera (by address).
  const std::vector<Eigen::Vector3d>& rays_for(const Camera& cam) const {
    if (ray_cam_ == &cam) return rays_;
    ray_cam_ = &cam;
    const int w = cam.width_px();
    const int h = cam.height_px();
    rays_.assign(static_cast<std::size_t>(w) * static_cast<std::size_t>(h) * 4,
                 Eigen::Vector3d::Zero());
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        for (int s = 0; s < 4; ++s) {
          // Pixel (x, y) spans [x - 0.5, x + 0.5] (OpenCV: integer coordinates at pixel centres).
          const Eigen::Vector2d px(x - 0.25 + 0.5 * (s % 2), y - 0.25 + 0.5 * (s / 2));
          const Eigen::Vector2d n = cam.undistort_normalized(cam.pixel_to_normalized(px));
          rays_[(static_cast<std::size_t>(y) * static_cast<std::size_t>(w) +
                 static_cast<std::size_t>(x)) *
                    4 +
                static_cast<std::size_t>(s)] = Eigen::Vector3d(n.x(), n.y(), 1.0);
        }
      }
    }
    return rays_;
  }

  boardcal::BoardSpec board_;
  boardcal::BoardImage tex_;
  int margin_ = 0;
  double px_per_m_ = 0;
  double u0_ = 0, v0_ = 0, sy_ = 1;
  std::size_t found_ = 0;
  mutable const Camera* ray_cam_ = nullptr;
  mutable std::vector<Eigen::Vector3d> rays_;
};

}  // namespace mocap::testing
