"""The one list of tracker names: the methods and their named variants (ablations), what each is,
and the colour figures draw it in. The CLI, the closed loop, the benchmarks and the figures all
read this; `make_tracker(name)` builds any of them.
"""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass(frozen=True)
class TrackerSpec:
    base: str  # the method that implements it: sift, ecc, deep_lk, hybrid
    config: dict = field(default_factory=dict)  # settings of that method's config that make this variant
    description: str = ""
    colour: str = "#7f7f7f"  # matplotlib colour; distinct across the registry


# the methods first, then the hybrid's ablations (each differs from `hybrid` in the named settings)
TRACKERS: dict[str, TrackerSpec] = {
    "hybrid": TrackerSpec("hybrid", {}, "the hybrid as shipped: global match, exposure-normalised colour OP_t gate, "
                          "feature LK, verified re-acquisition, scene motion, keyframe anchor, GRU", "#d62728"),
    "deep_lk": TrackerSpec("deep_lk", {"residual": False}, "the paper's Deep LK baseline (every frame aligned; its LK "
                           "and OP_t exposure-normalised)",
                           "#1f77b4"),
    "deep_lk_residual": TrackerSpec("deep_lk", {"residual": True, "verify_residual": False},
                                    "Deep LK + the residual regressor, always applied (the paper's Deep LK+Δ)",
                                    "#17becf"),
    "ecc": TrackerSpec("ecc", {}, "OpenCV ECC (the paper's LK-only baseline)", "#ff7f0e"),
    "sift": TrackerSpec("sift", {}, "SIFT keypoints + RANSAC similarity", "#2ca02c"),
    "hybrid_paper": TrackerSpec("hybrid", {"background": False, "colour_occlusion": False, "residual": True,
                                           "verify_residual": False, "normalise_exposure": False,
                                           "normalise_lk_exposure": False,
                                           "verify_reacquisition": False,
                                           "gate_after_alignment": False, "perspective": False,
                                           "lk_perspective": False},
                                "the hybrid as published: grey raw OP_t, GRU only, residual always applied, the "
                                "similarity reported",
                                "#9467bd"),
    "hybrid_seed_gate": TrackerSpec("hybrid", {"gate_after_alignment": False},
                                    "the OP_t gate at the unaligned seed only (the paper's rule)", "#dbdb8d"),
    "hybrid_grey": TrackerSpec("hybrid", {"colour_occlusion": False}, "OP_t in grey instead of colour", "#8c564b"),
    "hybrid_no_anchor": TrackerSpec("hybrid", {"reanchor": False}, "no re-anchoring on aligned keyframes",
                                    "#e377c2"),
    "hybrid_cv": TrackerSpec("hybrid", {"predictor": "constant_velocity"}, "constant velocity instead of the GRU",
                             "#bcbd22"),
    "hybrid_hold": TrackerSpec("hybrid", {"predictor": "hold"}, "hold the last position instead of the GRU",
                               "#7f7f7f"),
    "hybrid_continuity": TrackerSpec("hybrid", {"continuity": True},
                                     "a seed continuing the track needs no NCC score", "#aec7e8"),
    "hybrid_residual": TrackerSpec("hybrid", {"residual": True},
                                   "with the (verified) residual regressor, on the similarity LK's answers",
                                   "#ff9896"),
    "hybrid_residual_unverified": TrackerSpec("hybrid", {"residual": True, "verify_residual": False},
                                              "with the residual regressor, its correction always applied",
                                              "#c5b0d5"),
    "hybrid_raw_op": TrackerSpec("hybrid", {"normalise_exposure": False},
                                 "OP_t on raw intensities (the paper's), not exposure-normalised", "#c49c94"),
    "hybrid_raw_lk": TrackerSpec("hybrid", {"normalise_lk_exposure": False},
                                 "feature LK on the frame as it comes (the paper's), not scaled to the template's "
                                 "exposure", "#843c39"),
    "hybrid_full_lk": TrackerSpec("hybrid", {"lk": {"levels": ("pool2", "pool1", "conv1_2"), "iterations": (15, 10, 8),
                                                    "channels": None, "eps": 2e-3, "coarse_eps": 1e-2},
                                             "margin": 8, "always_search_as_taken": True, "search_near_first": False},
                                  "the hybrid's alignment before the speed work: feature LK from pool2, all 64 "
                                  "channels, 8 px margin, stopping at 2e-3 px, both global searches every frame",
                                  "#9edae5"),
    "hybrid_unverified_reacquisition": TrackerSpec("hybrid", {"verify_reacquisition": False},
                                                   "a far global-match jump is accepted without verification",
                                                   "#f7b6d2"),
    "hybrid_similarity_chain": TrackerSpec("hybrid", {"background_config": {"homography": False,
                                                                             "occluder_prior": False,
                                                                             "cell_corners": 0}},
                                           "the surroundings' motion as a similarity chain of the strongest corners, "
                                           "with no occluder prior (before the homography refit)", "#5254a3"),
    "hybrid_plane_refit": TrackerSpec("hybrid", {"background_config": {"grow_plane": False}},
                                      "each hop refitted as a homography on its similarity consensus's own inliers "
                                      "only, not grown into the plane that contains them", "#8ca252"),
    "hybrid_similarity_hops": TrackerSpec("hybrid", {"background_config": {"turn": False}},
                                          "a hop that does not carry a plane stays a similarity, not refitted as the "
                                          "camera's turn", "#d6616b"),
    "hybrid_predictor_guess": TrackerSpec("hybrid", {"scene_inertia_frames": 0},
                                          "where the surroundings give nothing, the predictor guesses at once (the "
                                          "paper's), not the scene's last measured motion first", "#e7969c"),
    "hybrid_similarity_report": TrackerSpec("hybrid", {"perspective": False},
                                            "the similarity is reported as the target's pose (the paper's), not "
                                            "corrected by the target's perspective measured on aligned frames",
                                            "#ad494a"),
    "hybrid_unchecked_alignment": TrackerSpec("hybrid", {"pull_check": False},
                                              "every alignment of a partly covered target is taken, not checked "
                                              "against the surroundings' motion", "#6b6ecf"),
    "hybrid_covered_pull": TrackerSpec("hybrid", {"pull_check_clear": False},
                                       "an alignment is checked against the surroundings only where OP_t says the "
                                       "target is partly covered, not also where it shows clear and the ring of "
                                       "picture around it changed", "#cedb9c"),
    "hybrid_aligned_pull": TrackerSpec("hybrid", {"pull_check_carried": False},
                                       "an alignment is checked against the surroundings only on the frame after an "
                                       "alignment, not also after frames they carried a covered target, and any "
                                       "better fit speaks for it however little the template tells the poses apart",
                                       "#9e6b39"),
    "hybrid_free_scale": TrackerSpec("hybrid", {"carried_scale_step": 0.0},
                                     "an alignment after frames the surroundings carried may change the target's "
                                     "scale by any amount up to max_scale_step, not only by what they carried",
                                     "#a55194"),
    "hybrid_clear_pull": TrackerSpec("hybrid", {"pull_evidence": 0.5},
                                     "an alignment the surroundings contradict is taken only where it fits the "
                                     "template clearly better than their pose, not wherever better", "#3182bd"),
    "hybrid_flat_lk": TrackerSpec("hybrid", {"lk_perspective": False},
                                  "the feature LK aligns the similarity alone (the paper's), not the similarity under "
                                  "the target's reported perspective", "#e6550d"),
    "hybrid_flat_drift": TrackerSpec("hybrid", {"lookalike_drift": False},
                                     "an alignment near the estimate (or the surroundings' estimate) may have drifted "
                                     "by the same allowance per frame with a look-alike in view, not only per frame "
                                     "guessed",
                                     "#756bb1"),
    "hybrid_first_consensus": TrackerSpec("hybrid", {"background_config": {"runner_up": False}},
                                          "a hop whose consensus the gate refuses offers no other, not the consensus "
                                          "among the points the first did not hold", "#9c9ede"),
    "hybrid_interleaved_hops": TrackerSpec("hybrid", {"background_config": {"fuse_hops": False}},
                                           "each frame's surroundings measured from the frame five back alone (five "
                                           "interleaved chains), not also from four back and the two averaged",
                                           "#fd8d3c"),
    "hybrid_steady_gate": TrackerSpec("hybrid", {"background_gate_sway": False},
                                      "the surroundings' gate is the same for every view, not widened by how much "
                                      "the view's per-frame motion has been changing", "#bd9e39"),
    "hybrid_estimate_gate": TrackerSpec("hybrid", {"background_gate_continues": False},
                                        "a measurement of the surroundings is judged from the estimate alone, not "
                                        "also from where the scene's measured motion carries the last measured "
                                        "position", "#e7ba52"),
    "hybrid_no_surroundings_veto": TrackerSpec("hybrid", {"surroundings_veto_frames": 0},
                                               "a far re-acquisition the surroundings contradict is not held back",
                                               "#b5cf6b"),
    "hybrid_no_context": TrackerSpec("hybrid", {"context_check": False},
                                     "the target's own surroundings never overrule the surroundings' veto on a far "
                                     "re-acquisition", "#7b4173"),
    "hybrid_homography": TrackerSpec("hybrid", {"warp": "homography"},
                                     "the hybrid estimating a homography (true perspective corners, what six-DOF "
                                     "servoing uses) instead of the paper's similarity", "#17a768"),
    "hybrid_no_cut_test": TrackerSpec("hybrid", {"cut_ncc": -1.0},
                                      "no scene-cut test: the surroundings' chain is trusted across a cut",
                                      "#393b79"),
    "hybrid_moving": TrackerSpec("hybrid", {"target_motion": "moving"},
                                 "the target moves on its own: no veto from the surroundings, the predictor alone "
                                 "fills gaps", "#637939"),
    "hybrid_auto_motion": TrackerSpec("hybrid", {"target_motion": "auto"},
                                      "static or moving chosen from the first aligned frames (what `track` runs)",
                                      "#8c6d31"),
}

TRACKER_NAMES = tuple(TRACKERS)
METHOD_NAMES = ("sift", "ecc", "deep_lk", "deep_lk_residual", "hybrid")  # the methods, without ablations
VARIANT_NAMES = tuple(n for n in TRACKERS if n not in METHOD_NAMES)
