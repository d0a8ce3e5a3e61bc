// Settings of incremental mapping (paper Sec. III, "Incremental Mapping Without Forgetting"):
// scans arrive one by one and only the current scan trains the map, with the decoder pretrained
// and frozen and the importance-weight regulariser against forgetting.
#pragma once

#include <string>

#include "shine/mapper/keyframe_policy.hpp"
#include "shine/optim/importance_weights.hpp"

namespace shine {

struct IncrementalConfig {
    /// Optimisation steps on each scan (the paper runs 50 at 0.5 m leaves), of batch_size samples
    /// each. With the scans thinned to preprocess.voxel_downsample_m = 0.2 m, 11 steps of 8192
    /// samples score 0.8 points below 40 steps of 4096 on the street (92.8 %, still above the
    /// scores before the speed work) in about 60 % of the time, so that a frame takes 0.1 s on
    /// two cores; 12 steps score 93.0 %, 15 steps 93.6 %. Fewer, larger steps update each touched
    /// feature row fewer times for the same samples (docs/performance.md).
    int iterations_per_frame = 11;
    /// Samples per step in incremental mode (replaces training.batch_size).
    int batch_size = 8192;
    /// Feature learning rate at the start of each scan's steps (replaces
    /// training.learning_rate in incremental mode; it decays to final_learning_rate_ratio of
    /// this over the scan's steps).
    float learning_rate = 0.02f;
    ImportanceConfig importance;  ///< lambda_r (0 = no regulariser) and Omega_m
    /// The frozen decoder: "builtin" (models/decoder_pretrained.yaml, compiled in; outdoors at
    /// leaves finer than 0.2 m models/decoder_pretrained_fine.yaml, pretrained at 0.1 m), a path to
    /// a file written by `shine pretrain`, a map.vdb (the decoder a batch run trained with its
    /// features, e.g. on an earlier recording of the same sensor), or "none" (start from the
    /// random decoder and train it online, as training.train_decoder says).
    std::string decoder_weights = "builtin";
    int mesh_every = 0;  ///< bake and mesh every K frames while mapping (0: only at the end)
    /// Half-width of the surface band in incremental mode (replaces sampling.surface_band_m):
    /// with one scan per training round, a narrow band (the paper's +-3 sigma) places the
    /// surface better; measured in docs/incremental.md.
    float surface_band_m = 0.15f;
    /// Normals of the current scan's endpoints are estimated among the endpoints of the current
    /// scan and the scans just before it, this many in all (1: the current scan alone), from
    /// normal_neighbors of them (replaces sampling.normal_neighbors in incremental mode). 7 scans
    /// and 10 neighbours score within 0.1 point of 10 and 16 on the street, in two thirds of the
    /// time (docs/performance.md). 16 neighbours, as batch mode, gain 0.8 points on the real walk
    /// (84.10 -> 84.86 % of the held-out rays within 10 cm) and 1.6 at 0.1 m, and cost the
    /// streets 0.01-0.03 points and about 2 ms a scan (docs/incremental.md).
    int normal_window_frames = 7;
    int normal_neighbors = 16;
    /// Each scan's steps draw their samples from the rays of this many most recent scans, the
    /// current one included (1: the current scan alone, as the paper). The scans are kept in
    /// memory with the normals they got when they were current (after thinning, about 24 bytes
    /// a point: a 30 k-point scan is 0.7 MB). The regulariser still weighs only what the current
    /// scan touched (Eq. (4)). Replaying earlier scans averages their noise and small pose
    /// errors the way batch mode does, where one scan alone pulls the surface to its own points:
    /// with 100 (and half of each step on the current scan) the real walk's held-out rays within
    /// 10 cm rise from 78.0 to 84.1 % and the simulated streets gain 0.2 points, for about 10 %
    /// more time per scan (docs/incremental.md).
    int replay_frames = 100;
    /// With replay_frames > 1: this share of each step's rays is drawn from the current scan
    /// alone, the rest uniformly from all replay_frames scans (the current one included), so that
    /// the newest scan's region is not starved as the replayed pool grows. 0: all uniformly.
    float replay_current_share = 0.5f;
    /// The importance pass (Eq. (4)) uses every n-th ray of the scan: Omega grows by the mean
    /// gradient norm over the scan's samples (see importance_weights.hpp), which a subsample
    /// estimates (every 16th ray: 0.05 points below every 8th on the street, in half the time;
    /// docs/performance.md).
    int importance_ray_stride = 16;
    /// Optimiser state (Adam's moments, anchors, master copy) is kept for the rows that one of
    /// the last `active_frames` frames trained, and dropped for the rest, so that its memory
    /// follows the region being mapped on a long drive (feature_row_state.hpp). 0: keep it all.
    /// The bundled 50-frame street never drops any at the default.
    int active_frames = 50;
    /// When the sequence ends (`shine map --mode incremental`, NeuralMap.consolidate()), this
    /// many more steps of batch_size samples over the kept scans (the last replay_frames), all
    /// drawn uniformly, before the map is baked: what each scan's few steps left unsettled is
    /// trained together, as batch mode trains, with the decoder still frozen, a fresh optimiser,
    /// batch mode's surface band (sampling.surface_band_m) and consolidation_learning_rate
    /// decaying (cosine) to final_learning_rate_ratio of it. 0: the map as the last scan left
    /// it. The maps during the run (progress meshes, checkpoints, odometry) are not affected.
    /// 1000 steps (batch mode's 0.2 m sample budget, 1000 x 8192 = 250 x 32768) take 4-8 s on
    /// two cores and lift the real walk's held-out rays within 10 cm from 84.89 to 88.5 % and
    /// the streets by 2-3 F-score points (docs/incremental.md).
    int consolidation_steps = 1000;
    float consolidation_learning_rate = 0.01f;
    /// Free-space samples per ray in the consolidation (the scans' own steps take
    /// sampling.free_samples, 1). Each consolidation step takes as many rays as a scan's step
    /// (batch_size / samples per ray), so its batch grows with the samples: the surface is
    /// trained as before, and the free space that later rays crossed, where a moving car or
    /// person was mapped before the filter saw through it, gets five samples a ray instead of one.
    /// On the street with 20 movers the ghost area falls from 3.55 to 2.28 % of the static
    /// surface and the streets without movers gain 0.2-0.3 F-score points (docs/movers.md).
    int consolidation_free_samples = 5;
    /// A continued map (shine map --from): the importance Omega the old map's rows are held with,
    /// in the new drive's steps and in the consolidation, where they are anchored at their saved
    /// values. At importance_cap (1) the new drive cannot improve the surfaces the old drive saw
    /// too; at 1e-4 it does, and what it does not see stays (the street of docs/continue.md,
    /// second drive without movers: F 95.39 % held at 1, 95.57 % at 1e-4, completion of the first
    /// drive 96.53 / 96.50 %; at 1e-5 the completion falls to 96.06 %).
    float old_rows_importance = 1e-4f;
    /// With estimated poses, which scans train the map when they come and which wait for the
    /// catch-up after the last scan (keyframe_policy.hpp). YAML section `keyframes`.
    KeyframeConfig keyframes;
};

}  // namespace shine
