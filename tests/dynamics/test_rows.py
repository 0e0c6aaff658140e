"""The model-independent kernels over rows (dynamics.rows): each gives what the model's own
kernel gives row by row, bit for bit, with shared or per-row parameters."""

import numpy as np
import pytest

from dynamics import rows, stepping

from .helpers import random_states

N = 5


@pytest.mark.parametrize("name", ["rolling_disk", "bead_on_driven_rod"])
def test_energy_and_residual_are_the_model_s_kernels_row_by_row(name):
    system, x = random_states(name, N, seed=4)
    m, p, T = system.kernel_module, system.parameter_vector, np.zeros(N)
    energy, residual = np.empty((N, 2)), np.empty((N, system.n_c))
    for b in range(N):
        m.energy_terms(0.0, x[b], p, energy[b])
        m.residual(0.0, x[b], p, residual[b])
    assert np.array_equal(system.energy_terms(x), energy)
    assert np.array_equal(system.constraint_residual(x), residual)
    # each row's own parameters: the same numbers when every row has p
    out, P = np.empty((N, 2)), np.tile(p, (N, 1))
    rows.state_batch(T, x, p, P, out, stepping.table(m, "energy_terms"), stepping.AT_ENERGY)
    assert np.array_equal(out, energy)


def test_outputs_and_power_follow_the_model_s_accelerations_row_by_row():
    system, x = random_states("eccentric_disk_slider", N, seed=5)  # outputs, and an input
    m, p = system.kernel_module, system.parameter_vector
    u = np.random.default_rng(6).normal(size=(N, system.n_u))
    K = m.K
    A, z = np.empty((K, K + 1)), np.empty(K)
    outputs, power = np.empty((N, len(system.output_names))), np.empty((N, 1))
    for b in range(N):
        m.accelerations(0.0, x[b], u[b], p, A, z)
        m.outputs(0.0, x[b], u[b], p, z, outputs[b])
        m.power_out(0.0, x[b], u[b], p, z, power[b])
    got = system.outputs(0.0, x, u)
    assert np.array_equal(np.column_stack([got[k] for k in system.output_names]), outputs)
    assert np.array_equal(system.power(0.0, x, u), power[:, 0])


def test_a_model_without_constraints_projects_nothing():
    system, x = random_states("two_link_arm", N, seed=7)
    assert stepping.table(system.kernel_module)[stepping.AT_PROJECT] == 0  # none compiled
    assert np.array_equal(system.project(x), x)
