import numpy as np
import pytest

from zrp_ga.operators import crossover, inversion, mutation, rotation, selection
from zrp_ga.operators.repair import repair

K = 36
LOW, UP = -np.ones(K), np.ones(K)
BLOCKS = [(0, 18), (18, 36)]


def _genomes(rng, N=200):
    return rng.uniform(LOW, UP, size=(N, K))


@pytest.mark.parametrize("op", [crossover.one_point, crossover.two_point, crossover.uniform])
def test_swapping_crossovers_exchange_genes_locus_by_locus(rng, op):
    A, B = _genomes(rng), _genomes(rng)
    a, b = A.copy(), B.copy()
    op(a, b, rng=rng)
    # every locus holds the two parents' genes, in one order or the other
    assert np.all(((a == A) & (b == B)) | ((a == B) & (b == A)))
    assert np.any(a != A)  # and something was exchanged


def test_two_point_swaps_numpy_individuals_in_place(rng):
    a, b = np.arange(10.0), -np.arange(10.0)
    out = crossover.two_point(a, b, rng=rng)
    assert out[0] is a and out[1] is b
    assert np.any(a < 0) and np.any(b > 0)  # DEAP's cxTwoPoint leaves numpy genomes unchanged
    np.testing.assert_array_equal(np.abs(a), np.arange(10.0))


@pytest.mark.parametrize("op", [crossover.blend, crossover.sbx])
def test_real_crossovers_keep_length_and_mean(rng, op):
    A, B = _genomes(rng), _genomes(rng)
    a, b = A.copy(), B.copy()
    kwargs = dict(low=LOW, up=UP) if op is crossover.sbx else {}
    op(a, b, rng=rng, **kwargs)
    assert a.shape == A.shape
    if op is crossover.blend:  # blend keeps the pair's mean exactly
        np.testing.assert_allclose(a + b, A + B, atol=1e-14)
    else:
        assert np.all((a >= LOW) & (a <= UP) & (b >= LOW) & (b <= UP))
        assert np.any(a != A)


@pytest.mark.parametrize("op", [mutation.gaussian, mutation.polynomial, mutation.uniform_reset])
def test_mutations_change_some_genes_and_bounded_ones_stay_in_range(rng, op):
    A = _genomes(rng)
    a = A.copy()
    op(a, rng=rng, low=LOW, up=UP)
    assert a.shape == A.shape and np.any(a != A)
    if op is not mutation.gaussian:
        assert np.all((a >= LOW) & (a <= UP))
    changed = np.mean(a != A)
    assert 0.05 < changed < 0.4  # about indpb of the genes


@pytest.mark.parametrize("op", [inversion.segment, rotation.segment])
def test_permutations_keep_the_multiset_and_reach_every_locus(rng, op):
    A = _genomes(rng, 2000)
    a = A.copy()
    op(a, rng=rng)
    np.testing.assert_array_equal(np.sort(a, axis=1), np.sort(A, axis=1))
    moved = np.any(a != A, axis=0)
    assert moved.all(), f"loci never moved: {np.flatnonzero(~moved)}"  # the last one included


@pytest.mark.parametrize("op", [inversion.block, rotation.block])
def test_block_permutations_stay_inside_a_block(rng, op):
    A = np.hstack([rng.uniform(0, 1, (500, 18)), rng.uniform(10, 11, (500, 18))])
    a = A.copy()
    op(a, rng=rng, blocks=BLOCKS)
    for lo, hi in BLOCKS:
        np.testing.assert_array_equal(np.sort(a[:, lo:hi], axis=1), np.sort(A[:, lo:hi], axis=1))
    assert np.any(a[:, :18] != A[:, :18]) and np.any(a[:, 18:] != A[:, 18:])
    assert np.all(np.any(a != A, axis=0))


def test_inversion_reverses_and_rotation_shifts_a_segment():
    g = np.arange(8.0)
    rng = np.random.default_rng(3)
    a = g.copy()
    inversion.segment(a, rng=rng)
    i, j = np.flatnonzero(a != g)[[0, -1]]
    np.testing.assert_array_equal(a[i : j + 1], g[i : j + 1][::-1])
    b = g.copy()
    rotation.segment(b, rng=rng)
    i, j = np.flatnonzero(b != g)[[0, -1]]
    seg = b[i : j + 1]
    k = int(np.flatnonzero(seg == g[i])[0])
    np.testing.assert_array_equal(np.roll(seg, -k), g[i : j + 1])


def test_single_genome_is_changed_in_place_deap_style(rng):
    ind = np.linspace(-1, 1, K)
    before = ind.copy()
    (out,) = mutation.gaussian(ind, rng=rng, low=LOW, up=UP, indpb=1.0)
    assert out is ind and np.all(ind != before)


def test_repair_clip_and_reflect():
    low, up = np.zeros(3), np.ones(3)
    np.testing.assert_allclose(repair(np.array([-0.2, 0.5, 1.3]), low, up, "clip"), [0, 0.5, 1])
    np.testing.assert_allclose(repair(np.array([-0.2, 0.5, 1.3]), low, up, "reflect"), [0.2, 0.5, 0.7])
    np.testing.assert_allclose(repair(np.array([2.25, -1.5, 3.0]), low, up, "reflect"), [0.25, 0.5, 1.0])
    with pytest.raises(ValueError, match="'wrap' is not a valid Repair"):
        repair(np.zeros(3), low, up, "wrap")


def test_selections_prefer_low_costs_and_treat_nan_as_worst(rng):
    costs = np.array([np.nan, 5.0, 1.0, np.inf, 3.0])
    picks = selection.tournament(costs, 5000, rng, size=3)
    counts = np.bincount(picks, minlength=5)
    assert counts[2] > counts[4] > counts[1]
    # NaN and inf win only tournaments with no finite entrant: (2/5)^3 = 6.4% of them
    assert 0.04 * 5000 < counts[0] + counts[3] < 0.09 * 5000
    picks = selection.truncation(costs, 1000, rng, fraction=0.4)
    assert set(picks) == {2, 4}


# --- every operator's parameters checked before any work (zrp_ga.operators.build) ---------------
@pytest.mark.parametrize(
    "node, key, missing",
    [({"_target_": "deap.tools.mutGaussian"}, "mutation.op", "mu"),  # DEAP's: mu, sigma, indpb without defaults
     ({"_target_": "deap.tools.mutGaussian", "mu": 0.0, "sigma": 0.1}, "mutation.op", "indpb"),
     ({"_target_": "deap.tools.selTournament"}, "selection.op", "tournsize"),
     ({"_target_": "deap.tools.cxBlend"}, "crossover.op", "alpha")],
)  # fmt: skip
def test_a_missing_operator_parameter_is_a_config_error_naming_key_and_parameter(rng, node, key, missing):
    from zrp_ga import operators
    from zrp_ga.core.schema import ConfigError

    family = key.split(".")[0]
    with pytest.raises(ConfigError, match=rf"^{key}\.{missing}: {node['_target_']} needs this parameter"):
        operators.build(node, key, family, rng, low=LOW, up=UP, blocks=BLOCKS)
    with pytest.raises(ConfigError, match=rf"^{key}\.{missing}:"):
        operators.target(node, key)  # what the GA checks when it is built, before any problem exists


def test_the_problems_ranges_count_as_given_but_only_where_build_binds_them(rng):
    from zrp_ga import operators
    from zrp_ga.core.schema import ConfigError

    node = {"_target_": "deap.tools.mutPolynomialBounded", "eta": 20.0, "indpb": 0.2}  # low, up: the problem's
    mutate = operators.build(node, "mutation.op", "mutation", rng, low=LOW, up=UP)
    a = np.zeros((3, K))
    mutate(a)
    assert np.all((a >= LOW) & (a <= UP)) and np.any(a != 0.0)
    with pytest.raises(ConfigError, match=r"^mutation.op.low: deap.tools.mutPolynomialBounded needs this parameter"):
        operators.build(node, "mutation.op", "mutation", rng)  # no ranges given: nothing would bind them


def test_operators_with_every_parameter_build(rng):
    from zrp_ga import operators

    node = {"_target_": "deap.tools.mutGaussian", "mu": 0.0, "sigma": 0.1, "indpb": 0.5}
    mutate = operators.build(node, "mutation.op", "mutation", rng, low=LOW, up=UP)
    a = np.zeros((4, K))
    mutate(a)
    assert np.any(a != 0.0)


def test_cli_refuses_a_deap_operator_without_its_parameters_before_any_work(tmp_path):
    import subprocess
    import sys

    proc = subprocess.run([sys.executable, "-m", "zrp_ga.cli", "mutation.op._target_=deap.tools.mutGaussian",
                           f"hydra.run.dir={tmp_path}/run", "progress=false"], capture_output=True, text=True, cwd=tmp_path)  # fmt: skip
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 2, proc.stderr
    assert lines == ["zrp-ga: error: mutation.op.mu: deap.tools.mutGaussian needs this parameter (missing: mu); "
                     "add +mutation.op.mu=VALUE"], proc.stderr  # fmt: skip
    assert not (tmp_path / "run").exists()  # refused before the run directory was made
