"""Large displacements (issue 12): the engine's stages, the initialisation stage, fusion, warm start,
temporal initialisation through FlowStream and the confidence, on exactly rendered pairs.

Frames come from flow_node.bag.scenes (continuous cosine textures sampled at the exact inverse motion), so
the ground truth is the rendered motion and never the engine's own interpolation. The solver settings are
small_frames' (realtime solved at full resolution, numpy backend) with a short pyramid (3 levels x 0.5): on
160x120 frames its coarsest level is 40x30, where a 40 px shift is still 10 px -- beyond what warping
recovers, so the pyramid alone fails and only an initialisation can rescue the pair.
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest
import small_frames

from flow_node.bag.scenes import AffineMotion, Layer, Scene, Texture
from flow_node.core import FlowEstimator
from flow_node.core.backends import NUMPY, select_backend
from flow_node.core.confidence import confidence
from flow_node.core.config import FlowConfig
from flow_node.core.densify import densify, forward_propagate, push_pull
from flow_node.core.engine import estimate_pair, start_level
from flow_node.core.fusion import data_cost, fuse
from flow_node.core.initialise import Candidate, forward_backward_consistent, in_background, initialise
from flow_node.core.metrics import confidence_auc
from flow_node.core.pyramid import make_pyramid
from flow_node.pipeline.stream import FlowStream, StreamSettings

SIZE = (160, 120)  # width, height
SHIFT = (40.0, 12.0)  # px per frame
SHORT = small_frames.CONFIG.replace(levels=3, scale_factor=0.5, min_size=8, initialisation="none")


def grey(rgb: np.ndarray) -> np.ndarray:
    return (rgb @ np.array([0.299, 0.587, 0.114])).astype(np.float32)


def pan(seed: int, shift: tuple[float, float] = SHIFT, size: tuple[int, int] = SIZE) -> Scene:
    """A textured plane translating by ``shift`` px/frame; the texture has structure from 1/100 to 1/5
    cycles/px (coarse enough that the large shift is not ambiguous)."""
    w, h = size
    return Scene("pan", size, (Layer(Texture.random(np.random.default_rng(seed), fmin=1 / 100),
                                     AffineMotion(((w - 1) / 2, (h - 1) / 2), shift)),))


def shifted_pair(seed: int = 0, shift: tuple[float, float] = SHIFT,
                 size: tuple[int, int] = SIZE) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(i0, i1, gt) of :func:`pan`, rendered exactly."""
    scene = pan(seed, shift, size)
    return grey(scene.render(0)), grey(scene.render(1)), scene.ground_truth(1).astype(np.float32)


def visible(gt: np.ndarray) -> np.ndarray:
    """Pixels whose x + gt stays inside the frame (the rest has no data in frame 1)."""
    h, w = gt.shape[:2]
    ys, xs = np.mgrid[0:h, 0:w]
    return (xs + gt[..., 0] >= 0) & (xs + gt[..., 0] <= w - 1) & (ys + gt[..., 1] >= 0) & (ys + gt[..., 1] <= h - 1)


def vis_aee(flow: np.ndarray, gt: np.ndarray) -> float:
    m = visible(gt)
    return float(np.mean(np.linalg.norm(flow[m] - gt[m], axis=-1)))


@pytest.fixture(scope="module")
def pair() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    return shifted_pair()


# ------------------------------------------------------------------------------------------ stage interface
def test_the_stages_compose_to_the_api(pair) -> None:
    """estimate_pair (photometric -> initialisation -> refinement -> fusion -> layout) is exactly what
    FlowEstimator returns, and without a candidate the refinement runs over every level from zero."""
    i0, i1, _ = pair
    flow, stats, _ = estimate_pair(i0, i1, SHORT, NUMPY)
    api = FlowEstimator(SHORT).estimate_grey(i0, i1)
    assert np.array_equal(flow, api.flow) and flow.shape == i0.shape + (2,) and flow.dtype == np.float32
    assert stats.start_level == -1 and stats.init == "" and all(n > 0 for n in stats.iterations)
    cands = initialise(i0, i1, SHORT.replace(initialisation="dis_medium"))
    assert [c.name for c in cands] == ["dis_medium"] and cands[0].flow.shape == (2,) + i0.shape
    assert initialise(i0, i1, SHORT) == []  # none: the pyramid alone


def test_fusion_takes_the_candidate_of_least_data_cost(pair) -> None:
    i0, i1, gt = pair
    truth = np.moveaxis(gt, -1, 0).copy()
    wrong = truth + np.float32(5.0)
    fused, choice = fuse(i0, i1, [wrong, truth])
    inner = visible(gt)[10:-10, 10:-10]
    assert np.mean(choice[10:-10, 10:-10][inner] == 1) > 0.95
    assert vis_aee(np.moveaxis(fused, 0, -1), gt) < 0.5
    cost_t, cost_w = data_cost(i0, i1, truth), data_cost(i0, i1, wrong)
    both = np.isfinite(cost_t) & np.isfinite(cost_w)
    assert np.median(cost_t[both]) < 0.2 * np.median(cost_w[both])


def test_a_wrong_candidate_does_not_win_where_the_background_is_occluded() -> None:
    """A textured box jumps 60 px over a flat background. The background it covers in frame 1 is occluded:
    its true flow (zero) has no match there, so a candidate sending it onto flat background elsewhere costs
    far less than the truth. That candidate fails its forward-backward check there, so fusion continues the
    neighbours' flow (the still background) instead; on the box, where the reference (the pyramid) lost
    the motion and the candidate is right and consistent, the candidate wins."""
    w, h = 200, 160
    flat = Texture(np.zeros((0, 2)), np.zeros(0), np.zeros(0), np.ones(3))
    box = Layer(Texture.random(np.random.default_rng(5), fmax=1 / 6), AffineMotion((50.0, 80.0), (60.0, 0.0)),
                (50.0, 80.0, 20.0, 20.0, "box"))
    scene = Scene("jump", (w, h), (Layer(flat, AffineMotion(((w - 1) / 2, (h - 1) / 2))), box))
    i0, i1 = grey(scene.render(0)), grey(scene.render(1))
    truth = np.moveaxis(scene.ground_truth(1).astype(np.float32), -1, 0)
    ys, xs = np.mgrid[0:h, 0:w]
    box0 = (np.abs(xs - 50) <= 20) & (np.abs(ys - 80) <= 20)
    occluded = (np.abs(xs - 110) <= 20) & (np.abs(ys - 80) <= 20)  # the box in frame 1 (no overlap with box0)
    assert np.abs(truth[:, box0] - [[60.0], [0.0]]).max() == 0 and np.abs(truth[:, occluded]).max() == 0
    reference = truth.copy()
    reference[:, box0] = 0.0  # the pyramid lost the box
    candidate = truth.copy()
    candidate[1, occluded] = -55.0  # onto the flat background above the box
    backward = np.zeros_like(truth)
    backward[0, occluded] = -60.0  # the true flow frame 1 -> frame 0
    ok = forward_backward_consistent(candidate, backward)
    assert not ok[occluded].any() and ok[box0].all()
    inner = occluded & (np.abs(xs - 110) <= 12) & (np.abs(ys - 80) <= 12)
    cost_truth, cost_wrong = data_cost(i0, i1, truth), data_cost(i0, i1, candidate)
    assert np.median(cost_wrong[inner]) < 0.3 * np.median(cost_truth[inner])  # the cost would pick it
    fused, choice = fuse(i0, i1, [reference, candidate], [None, ok])
    by_cost, _ = fuse(i0, i1, [reference, candidate], [None, ok], propagate=False)
    err_fused, err_cost = (np.hypot(*(f - truth)) for f in (fused, by_cost))
    assert err_cost[inner].min() > 50.0  # without the rule the wrong flow wins on the occluded pixels
    assert err_fused[occluded].max() == 0.0  # with it, the background's own flow
    assert err_fused[box0].max() == 0.0 and np.all(choice[box0] == 1)


# ------------------------------------------------------------------------------------------ initialisation
@pytest.mark.parametrize("init,size", [("sift", SIZE), ("orb", SIZE), ("dis_medium", (240, 180)),
                                       ("dis_fine", (240, 180))])
def test_initialisation_recovers_a_40px_shift_the_pyramid_loses(init, size) -> None:
    """(DIS's own pyramid is too short for 40 px on 160x120 -- measured 39 px AEE -- so it gets 240x180.)"""
    i0, i1, gt = shifted_pair(0, SHIFT, size)
    none = FlowEstimator(SHORT).estimate_grey(i0, i1)
    with_init = FlowEstimator(SHORT.replace(initialisation=init)).estimate_grey(i0, i1)
    assert vis_aee(none.flow, gt) > 10.0  # the short pyramid alone is lost (measured ~39)
    assert vis_aee(with_init.flow, gt) < 0.1  # measured 0.001-0.02
    assert with_init.stats.init.split("+")[0] == init and with_init.stats.init_share > 0.3


def test_garbage_initialisation_does_not_make_a_pair_worse() -> None:
    """A small shift the pyramid solves, and a warm start that is wrong everywhere (a 30 px shift the
    other way, plus noise): fusion keeps the pyramid's flow."""
    i0, i1, gt = shifted_pair(seed=3, shift=(2.3, -1.4))
    rng = np.random.default_rng(0)
    garbage = np.empty(gt.shape, np.float32)
    garbage[..., 0] = -30.0 + rng.normal(0, 3, gt.shape[:2])
    garbage[..., 1] = 25.0 + rng.normal(0, 3, gt.shape[:2])
    est = FlowEstimator(SHORT)
    plain = vis_aee(est.estimate_grey(i0, i1).flow, gt)
    warm = est.estimate_grey(i0, i1, initial_flow=garbage)
    assert plain < 0.2
    assert vis_aee(warm.flow, gt) <= 1.1 * plain + 0.01
    assert warm.stats.init_share < 0.05  # the garbage was (almost) never taken


def test_warm_start_enters_at_the_trusted_level_not_the_coarsest(pair) -> None:
    """An exact warm start is used on the level init_scale names (not shrunk to the coarsest): the 40 px
    shift comes out right, and the levels above the start level were solved only for the fusion."""
    i0, i1, gt = pair
    cfg = SHORT.replace(init_scale=0.5)
    res = FlowEstimator(cfg).estimate_grey(i0, i1, initial_flow=gt)
    pyr = make_pyramid(i0, i1, cfg)
    assert start_level(pyr, cfg) == 1 == res.stats.start_level  # 80x60, half size
    assert start_level(pyr, SHORT.replace(init_scale=1.0)) == 0
    assert start_level(pyr, SHORT.replace(init_scale=0.01)) == pyr.coarsest
    assert res.stats.init == "initial_flow" and res.stats.init_share > 0.6  # measured 0.83
    assert vis_aee(res.flow, gt) < 0.3


@pytest.mark.parametrize("photometric", ["normalise", "census"])
def test_a_level_s_cost_planes_are_built_once(pair, photometric) -> None:
    """The fusion's cost planes (the backend's ``cost_planes``, each frame's) are built once per fused level: when the
    start level is the finest solved one (both fusions there, as with realtime's and fastest's
    init_finest_level on a pair DIS moves far) the second fusion reuses the first's, two calls per pair, not four;
    on two levels (start level 1, then the finest, 0) two each."""
    i0, i1, gt = pair
    backend = select_backend("auto")
    calls: list[tuple[int, ...]] = []

    def counting(img: np.ndarray, mode: str, eps: float) -> np.ndarray:
        calls.append(img.shape)
        return backend.cost_planes(img, mode, eps)

    for init_scale, shapes in ((1.0, [(120, 160)] * 2), (0.5, [(60, 80)] * 2 + [(120, 160)] * 2)):
        calls.clear()
        cfg = SHORT.replace(init_scale=init_scale, photometric=photometric)
        res = FlowEstimator(cfg, backend=backend._replace(cost_planes=counting)).estimate_grey(i0, i1, initial_flow=gt)
        assert res.stats.init == "initial_flow" and res.stats.start_level == (0 if init_scale == 1.0 else 1)
        assert calls == shapes


# ------------------------------------------------------------------------------------------ temporal
def _turning_pan(seed: int, size: tuple[int, int]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(i0, i1, gt): a textured plane moving 36 px right and 10 px up while turning by 1 degree and zooming
    by 1 %, rendered exactly (so the flow differs at every pixel: an upsampled coarse flow is not exact)."""
    w, h = size
    motion = AffineMotion(((w - 1) / 2, (h - 1) / 2), (36.0, -10.0), theta=np.deg2rad(1.0), scale=1.01)
    scene = Scene("turn", size, (Layer(Texture.random(np.random.default_rng(seed), fmin=1 / 100), motion),))
    return grey(scene.render(0)), grey(scene.render(1)), scene.ground_truth(1).astype(np.float32)


def test_init_finest_level_refines_a_far_moving_pair_only_down_to_that_level() -> None:
    """``init_finest_level`` (realtime's and fastest's 2): a pair the initialisation finds moving ~37 px is
    refined down to quarter size only -- no iterations on the two finer levels -- and its flow, upsampled to
    the input size, keeps the motion to a fraction of a pixel (measured 0.20 px; 0.14 refined down to full
    size, the precision the setting trades for time); a small motion, and a caller's warm start alone, are
    still solved at full size."""
    size = (480, 360)
    cfg = small_frames.CONFIG.replace(levels=5, initialisation="dis_ultrafast", init_finest_level=2)
    i0, i1, gt = _turning_pan(6, size)
    far = FlowEstimator(cfg).estimate_grey(i0, i1)
    full = FlowEstimator(cfg.replace(init_finest_level=0)).estimate_grey(i0, i1)
    assert far.flow.shape == (360, 480, 2) and far.stats.init == "dis_ultrafast" and far.stats.start_level == 2
    assert far.stats.iterations[:2] == [0, 0] and far.stats.iterations[2] > 0
    assert full.stats.iterations[0] > 0
    assert vis_aee(far.flow, gt) < 0.3 and vis_aee(full.flow, gt) < 0.2
    assert vis_aee(far.flow, gt) <= 2.0 * vis_aee(full.flow, gt)
    s0, s1, sgt = shifted_pair(5, (2.3, -1.4), size)  # below init_min_motion: no candidate, full size
    small = FlowEstimator(cfg).estimate_grey(s0, s1)
    assert small.stats.init == "" and small.stats.iterations[0] > 0 and vis_aee(small.flow, sgt) < 0.1
    warm = FlowEstimator(cfg.replace(initialisation="none")).estimate_grey(i0, i1, initial_flow=gt)
    assert warm.stats.init == "initial_flow" and warm.stats.iterations[0] > 0


def test_forward_propagation_carries_flow_to_the_next_frame() -> None:
    flow = np.zeros((2, 40, 50), np.float32)
    flow[0] = 3.0
    flow[:, 10:20, 10:20] = np.array([8.0, 2.0], np.float32)[:, None, None]  # a fast box in front
    out, weight = forward_propagate(flow)
    assert weight[:, :3].sum() == 0 and weight[:, 3:].all(axis=0)[:9].all()  # disoccluded left strip
    assert np.allclose(out[:, 12:22, 18:28], np.array([8.0, 2.0])[:, None, None])  # box moved by (8, 2)
    assert np.allclose(out[0, 30:, 10:40], 3.0)
    dense = push_pull(out, weight)
    assert np.allclose(dense[0, 30:, :3], 3.0, atol=0.5)  # holes filled from their neighbours
    assert densify(np.zeros((40, 50), np.float32), out, weight).shape == (2, 40, 50)


def test_temporal_initialisation_through_flowstream() -> None:
    """Three frames of a constant 40 px/frame motion: the first pair has only SIFT matches to go on; with
    temporal_init the second pair also starts from the first pair's flow carried forward."""
    scene = pan(5)
    frames = [grey(scene.render(t)) for t in range(3)]
    gt = scene.ground_truth(2).astype(np.float32)
    cfg = SHORT.replace(initialisation="sift")
    results = {}
    for temporal in (0, 1):
        stream = FlowStream(StreamSettings(config=cfg.replace(temporal_init=temporal)))
        outs = [stream.process(f, 1000 * t) for t, f in enumerate(frames)]
        assert outs[0] is None
        results[temporal] = outs[2]
    assert results[0].stats.init == "sift"
    assert results[1].stats.init == "previous+sift"
    assert vis_aee(results[1].flow, gt) < 0.5
    assert vis_aee(results[1].flow, gt) <= 1.1 * vis_aee(results[0].flow, gt) + 0.05
    # a reset forgets the previous flow: the next pair has the matches only
    stream.reset()
    stream.process(frames[0], 5000)
    assert stream.process(frames[1], 6000).stats.init == "sift"


def test_temporal_initialisation_alone_rescues_the_next_pair() -> None:
    """Without any per-pair initialisation the short pyramid loses the 40 px motion; with temporal_init the
    API's previous_flow (what the stream passes) carried forward gets the next pair right."""
    scene = pan(6)
    f1, f2 = grey(scene.render(1)), grey(scene.render(2))
    prev = scene.ground_truth(1).astype(np.float32)  # the previous pair's flow, on frame 0's grid
    gt = scene.ground_truth(2).astype(np.float32)
    est = FlowEstimator(SHORT.replace(temporal_init=1))
    assert vis_aee(est.estimate_grey(f1, f2).flow, gt) > 10.0
    res = est.estimate_grey(f1, f2, previous_flow=prev)
    assert res.stats.init == "previous" and vis_aee(res.flow, gt) < 0.5
    assert FlowEstimator(SHORT).estimate_grey(f1, f2, previous_flow=prev).stats.init == ""  # option off


# ------------------------------------------------------------------------------------------ confidence
def test_confidence_is_low_where_occluded_or_wrong_and_high_where_right() -> None:
    """A box moving 12 px over a still background: at the true flow, pixels that the box covers in frame 1
    (occluded) get low confidence, the rest high; a flow off by 3 px gets low confidence everywhere."""
    w, h = SIZE
    rng = np.random.default_rng(8)
    bg = Layer(Texture.random(rng), AffineMotion(((w - 1) / 2, (h - 1) / 2)))
    box = Layer(Texture.random(rng, fmax=1 / 6), AffineMotion((60.0, 60.0), (12.0, 0.0)),
                (60.0, 60.0, 20.0, 25.0, "box"))
    scene = Scene("box", SIZE, (bg, box))
    i0, i1 = grey(scene.render(0)), grey(scene.render(1))
    gt = scene.ground_truth(1).astype(np.float32)
    ys, xs = np.mgrid[0:h, 0:w]
    occluded = (np.abs(xs - (60 + 12)) <= 20) & (np.abs(ys - 60) <= 25) & (np.abs(xs - 60) > 20)
    occluded &= np.abs(ys - 60) <= 22  # away from the box's top/bottom edge
    right = (np.abs(xs - 60) > 40) | (np.abs(ys - 60) > 32)
    right &= (xs > 8) & (xs < w - 8) & (ys > 8) & (ys < h - 8)
    conf = confidence(i0, i1, gt)
    assert conf.dtype == np.float32 and conf.shape == (h, w) and 0.0 <= conf.min() and conf.max() <= 1.0
    assert np.mean(conf[occluded]) < 0.3
    assert np.mean(conf[right]) > 0.7
    wrong = gt + np.float32(3.0)
    assert np.mean(confidence(i0, i1, wrong)[right]) < 0.3
    # as a ranking of the real error: occluded pixels of a solved flow are the wrong ones
    flow = FlowEstimator(small_frames.CONFIG).estimate_grey(i0, i1).flow
    auc = confidence_auc(confidence(i0, i1, flow), flow, gt)
    assert auc is not None and auc > 0.75


def test_confidence_auc_is_one_for_a_perfect_ranking_and_half_for_noise() -> None:
    gt = np.zeros((20, 30, 2), np.float32)
    flow = gt.copy()
    flow[:10] += 5.0  # top half wrong
    conf = np.ones((20, 30), np.float32)
    conf[:10] = 0.1
    assert confidence_auc(conf, flow, gt) == pytest.approx(1.0)
    assert confidence_auc(1.0 - conf, flow, gt) == pytest.approx(0.0)
    noise = np.random.default_rng(0).random((20, 30)).astype(np.float32)
    assert abs(confidence_auc(noise, flow, gt) - 0.5) < 0.1
    assert confidence_auc(conf, gt, gt) is None  # every pixel right: no ranking to judge


def test_a_computed_initialisation_is_fused_only_for_large_motions() -> None:
    """A 2 px shift is below init_min_motion (24 px): only the cheap DIS gate runs, nothing is fused (the
    result is the pyramid's own, bit for bit); a 40 px shift is above it and DIS is fused."""
    i0, i1, _ = shifted_pair(seed=3, shift=(2.3, -1.4), size=(240, 180))
    cfg = SHORT.replace(initialisation="dis_medium")
    small = FlowEstimator(cfg).estimate_grey(i0, i1)
    assert small.stats.init_offered == "" and small.stats.init == "" and small.stats.start_level == -1
    assert np.array_equal(small.flow, FlowEstimator(SHORT).estimate_grey(i0, i1).flow)
    j0, j1, _ = shifted_pair(0, SHIFT, (240, 180))
    assert FlowEstimator(cfg).estimate_grey(j0, j1).stats.init == "dis_medium"


@pytest.mark.parametrize("preset", ["dis_ultrafast", "dis_medium"])
def test_the_gate_passes_every_pair_the_preset_would_fuse_unchanged(preset) -> None:
    """The gate (DIS ultrafast on the half-size pair) decides only whether the preset's own DIS runs: a
    30 px pan gets exactly the candidate a direct DIS run gives (forward and backward, bit for bit); a
    15 px pan -- under init_min_motion but over the gate's fraction of it -- runs the preset's DIS too,
    which then judges it not far; a 2 px pan stops at the gate (no candidate)."""
    import cv2

    from flow_node.core.initialise import DIS_PRESETS, dis_candidates, to_u8

    for shift, names, far in (((30.0, 0.0), [preset], True), ((15.0, 2.0), [preset], False),
                              ((2.0, 1.0), [], None)):
        i0, i1, _ = shifted_pair(1, shift, (240, 180))
        cands = dis_candidates(i0, i1, preset, 24.0)
        assert [c.name for c in cands] == names and (not cands or cands[0].far is far)
        if far:
            algo = cv2.DISOpticalFlow_create(DIS_PRESETS[preset][0])
            u0, u1 = to_u8(i0), to_u8(i1)
            assert np.array_equal(cands[0].flow, np.moveaxis(algo.calc(u0, u1, None), -1, 0))
            assert np.array_equal(cands[0].backward_flow(), np.moveaxis(algo.calc(u1, u0, None), -1, 0))


def test_a_small_object_moving_far_is_far_by_the_tail() -> None:
    """2 % of the pixels moving 50 px over a still scene (../shared/data/large's toy square) is far: the 95th
    percentile is 0, the 99th beyond TAIL_FACTOR x init_min_motion; the same object moving 30 px (under 1.5 x
    24) is not, nor 0.5 % moving 50 px. The gate's count test says the same on squared magnitudes."""
    from flow_node.core.initialise import TAIL_FACTOR, beyond, moves_far

    assert TAIL_FACTOR * 24.0 < 50.0
    for share, speed, far in ((0.02, 50.0, True), (0.02, 30.0, False), (0.005, 50.0, False), (0.06, 30.0, True)):
        flow = np.zeros((2, 200, 200), np.float32)
        flow[0, np.random.default_rng(0).random((200, 200)) < share] = speed  # spread: moves_far samples
        assert moves_far(flow, 24.0) is far, (share, speed)
        assert beyond(flow[0] ** 2 + flow[1] ** 2, 24.0) is far, (share, speed)


def test_a_backward_flow_computed_in_the_background_is_waited_for_and_its_error_raised() -> None:
    """Candidate.backward_flow waits for a backward flow still computing (initialise.in_background) and
    re-raises its error in the caller (here: OpenCV refusing frames of different sizes)."""
    ones = np.ones((2, 4, 5), np.float32)
    assert np.array_equal(Candidate("x", ones, in_background(lambda: 2 * ones)).backward_flow(), 2 * ones)
    algo = cv2.DISOpticalFlow_create(cv2.DISOPTICAL_FLOW_PRESET_ULTRAFAST)
    bad = Candidate("x", ones, in_background(lambda: algo.calc(np.zeros((32, 32), np.uint8),
                                                               np.zeros((40, 32), np.uint8), None)))
    with pytest.raises(cv2.error):
        bad.backward_flow()
    assert Candidate("x", ones).backward_flow() is None


def test_to_u8_rounds_half_to_even_and_clips() -> None:
    """The OpenCV conversion equals np.clip(np.rint(x * 255), 0, 255) on values below 0, above 1 and on
    the rounding boundaries (k + 1/2) / 255 and their neighbouring floats."""
    from flow_node.core.initialise import to_u8

    k = np.arange(-20, 280, dtype=np.float64)
    x = np.concatenate([(k + 0.5) / 255, k / 255, np.linspace(-0.3, 1.3, 5001)]).astype(np.float32)
    x = np.concatenate([x, np.nextafter(x, np.float32(2)), np.nextafter(x, np.float32(-2))]).reshape(3, -1)
    assert np.array_equal(to_u8(x), np.clip(np.rint(x * np.float32(255)), 0, 255).astype(np.uint8))


@pytest.mark.parametrize("shape", [(2, 2), (8, 40), (40, 11), (15, 15)])
def test_every_preset_runs_on_frames_too_small_for_dis(shape) -> None:
    """OpenCV's DIS refuses frames under 12 px a side (cv2.error): such a pair runs the pyramid alone, with
    the presets that start from DIS as with the rest (found by the fuzz layer under colcon test)."""
    rng = np.random.default_rng(3)
    f0 = rng.random(shape, dtype=np.float32)
    f1 = np.roll(f0, 1, axis=1)
    for name in ("quality", "balanced", "realtime", "fastest"):
        cfg = FlowConfig.preset(name).replace(backend="numpy", iterations=3)
        assert cfg.initialisation.startswith("dis")
        flow = FlowEstimator(cfg).estimate(f0, f1).flow
        assert flow.shape == shape + (2,) and np.isfinite(flow).all()
