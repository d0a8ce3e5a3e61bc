// The frame a map's poses came in, and the frame the map was made in. A batch map refines its
// scans' poses (mapper/pose_refinement.hpp): its surfaces sit where the refined poses put them,
// which differ from the given ones by centimetres that vary along the drive (the gauge, and a
// slow bend where the given poses were good and the map's registration weakly constrained).
// A pose found in the map (`shine localize`) is therefore in the map's frame; the user's poses
// of other drives, and what they compare against, are in the given poses' frame.
//
// PoseFrameCorrection carries a pose between the two with the corrections of the map's scans
// near it: each scan k has C_k = T_given(k) T_refined(k)^-1, a rigid transform of the world that
// takes its neighbourhood from the map's frame to the given one. At a pose T with position p the
// corrections are blended with Gaussian weights on the distance from p to each scan (the nearest
// scan's distance subtracted, so that a pose far from every scan still takes the nearest ones):
// the displacement C_k(p) - p and the rotation of C_k, averaged (the rotations as unit
// quaternions in one hemisphere, normalised). Blending over a few metres follows the slow bend
// and averages out the scans' own noise.
//
// Measured on the real walk (map of the even scans, odd scans localised, against the recording's
// poses): median error 4.48 cm in the map's frame, 0.65 cm with the nearest scan's correction,
// 0.49 / 0.79 / 1.46 / 3.07 cm blended over 1 / 3 / 5 / 10 m; the real drive (2 m between scans):
// 2.51 cm, 1.10 cm nearest, 0.92 / 0.77 / 1.05 / 1.97 cm (docs/localize.md).
#pragma once

#include <Eigen/Geometry>
#include <vector>

namespace shine {

class PoseFrameCorrection {
  public:
    /// Blending length of the default, m: 3 m (see the file comment).
    static constexpr double kDefaultSigmaM = 3.0;

    /// `given[k]` and `refined[k]` are scan k's poses in the two frames (T_world_sensor). Throws
    /// DataError when the counts differ or there is no scan; sigma_m must be positive.
    PoseFrameCorrection(std::vector<Eigen::Isometry3d> given,
                        std::vector<Eigen::Isometry3d> refined, double sigma_m = kDefaultSigmaM);

    /// A pose of the map's frame in the given poses' frame.
    Eigen::Isometry3d to_given(const Eigen::Isometry3d& T_map_frame) const;
    /// A pose of the given poses' frame in the map's frame (the inverse blend, weighted by the
    /// distance to the given positions).
    Eigen::Isometry3d to_map(const Eigen::Isometry3d& T_given_frame) const;

    std::size_t num_scans() const { return given_.size(); }

  private:
    /// The blend at `T` of the transforms `from_to[k]`, weighted by the distance from T to
    /// `anchors[k]`.
    Eigen::Isometry3d blend(const Eigen::Isometry3d& T,
                            const std::vector<Eigen::Isometry3d>& anchors,
                            const std::vector<Eigen::Isometry3d>& from_to) const;

    std::vector<Eigen::Isometry3d> given_, refined_;
    std::vector<Eigen::Isometry3d> map_to_given_;  ///< C_k
    std::vector<Eigen::Isometry3d> given_to_map_;  ///< C_k^-1
    double sigma_m_;
};

}  // namespace shine
