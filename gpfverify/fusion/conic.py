"""Parametrised (DPP) cvxpy problems re-solved by Clarabel without cvxpy's per-solve work.

cvxpy compiles a DPP problem into the conic program

    min ½uᵀPu + qᵀu  s.t.  b − Au ∈ K,

whose data are affine in the parameter vector p (every parameter flattened column-major, then a 1):
the nonzeros of [A  b] are T p for a sparse tensor T that cvxpy builds once. ``Problem.solve`` still
spends most of a small solve re-applying p through its generic machinery and inverting its whole
reduction chain. :meth:`ClarabelProgram.compile` takes T, the sparsity pattern, P, q and the cones
from cvxpy once; :meth:`ClarabelProgram.solve` forms the data with the same sparse product cvxpy
computes (so Clarabel receives the same bits; compiling checks this), builds a fresh
``clarabel.DefaultSolver`` with default settings (so a solve is a function of its parameter values
alone, never of an earlier solve), and maps the solution back as cvxpy does: each variable is
recovered by cvxpy's own ``recover_value_for_leaf`` from its entries of Clarabel's u, requested
duals are entries of Clarabel's z, and the objective and requested values are cvxpy's expressions
evaluated there. Those entries are found once by running cvxpy's inversion on a probe solution.
Compiling refuses what this cannot reproduce: parameters cvxpy rewrites (``symmetric=True`` and
other dimension-reducing attributes), a P that depends on parameters, diag/sparse variables.

:func:`solve_with_cvxpy` solves the same :class:`Parametrised` problem through cvxpy (any solver),
so both routes return one :class:`ConicSolution`.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from types import SimpleNamespace
from collections.abc import Sequence

import clarabel
import cvxpy as cp
import cvxpy.settings as cvxpy_status
import numpy as np
import scipy.sparse as sp

from gpfverify.errors import SolverError
from gpfverify.fusion.quiet import solver_output_discarded

# cvxpy's internals (run against cvxpy 1.9): a cvxpy that moved them makes compile refuse, and
# callers solve through cvxpy's public route instead (the same numbers, slower)
try:
    from cvxpy.cvxcore.python.canonInterface import lo
    from cvxpy.reductions.cvx_attr2constr import (SYMMETRIC_ATTRIBUTES, attributes_present,
                                                  recover_value_for_leaf)
    from cvxpy.reductions.solvers.conic_solvers.clarabel_conif import CLARABEL, dims_to_solver_cones
except ImportError as missing:
    _MISSING_INTERNALS: ImportError | None = missing
else:
    _MISSING_INTERNALS = None


@dataclass(frozen=True)
class Parametrised:
    """A DPP problem with the parameters a solve sets (in the order values are passed), the
    expressions whose values and the constraints whose dual values a solve returns."""

    problem: cp.Problem
    parameters: tuple[cp.Parameter, ...]
    values: tuple[cp.Expression, ...]
    duals: tuple[cp.Constraint, ...]


@dataclass(frozen=True)
class ConicSolution:
    """cvxpy's status name; when it reports a solution (``status in cvxpy.settings.SOLUTION_PRESENT``)
    the objective ``value`` and the arrays ``values``/``duals`` of :class:`Parametrised`, else NaN
    and empty tuples."""

    status: str
    value: float
    values: tuple[np.ndarray, ...]
    duals: tuple[np.ndarray, ...]


def _solution(status: str, value, values, duals) -> ConicSolution:
    if status in cvxpy_status.ERROR:
        raise SolverError(f"the solver failed (status {status})")
    if status not in cvxpy_status.SOLUTION_PRESENT:
        return ConicSolution(status, float("nan"), (), ())
    return ConicSolution(status, float(value), tuple(np.asarray(v, dtype=float) for v in values),
                         tuple(np.asarray(d, dtype=float) for d in duals))


def solve_with_cvxpy(program: Parametrised, parameter_values: Sequence, solver: str) -> ConicSolution:
    """Set the parameters and solve through cvxpy with ``warm_start=False`` (a new solver object,
    not one updated from the previous solve), the solver's own printing discarded
    (:func:`~gpfverify.fusion.quiet.solver_output_discarded`). Raises SolverError when the solver
    fails."""
    for parameter, value in zip(program.parameters, parameter_values, strict=True):
        parameter.value = value
    try:
        with solver_output_discarded():
            program.problem.solve(solver=solver, warm_start=False)
    except cp.SolverError as exc:
        raise SolverError(str(exc)) from None
    return _solution(program.problem.status, program.problem.value,
                     [e.value for e in program.values], [c.dual_value for c in program.duals])


def _probe_value(parameter: cp.Parameter) -> np.ndarray:
    """Distinct nonzero values for compiling (any values give the same tensor), or the parameter's
    value if it has one."""
    if parameter.value is not None:
        return parameter.value
    return np.arange(1.0, parameter.size + 1.0).reshape(parameter.shape, order="F") / parameter.size


def _lowered_index(variable: cp.Variable, full_index: np.ndarray) -> np.ndarray:
    """Entries of u that cvxpy's CvxAttr2Constr gives ``variable`` before it recovers the full value:
    the upper triangle (row-major, as numpy.triu_indices) for a symmetric/PSD/NSD variable, all
    entries otherwise; ValueError for attributes with another lowered form (diag, sparsity)."""
    if variable.attributes["diag"] or variable.attributes["sparsity"]:
        raise ValueError(f"{variable} has a diag/sparsity attribute; compile does not support it")
    if attributes_present([variable], SYMMETRIC_ATTRIBUTES):
        return full_index[np.triu_indices(variable.shape[-1])]
    return full_index


def _selection(read: np.ndarray, probe: np.ndarray, what: str) -> np.ndarray:
    """Indices i with read = probe[i] (probe = 1, 2, 3, …), or ValueError if ``read`` is not a
    plain selection of the probe's entries."""
    index = np.asarray(read, dtype=float).astype(np.intp) - 1
    if not (np.all((index >= 0) & (index < probe.size)) and np.array_equal(probe[index], read)):
        raise ValueError(f"{what} is not an entry of Clarabel's solution; compile does not support it")
    return index


def _evaluated_parameters(program: Parametrised) -> tuple[int, ...]:
    """Positions of the parameters the objective or a requested value depends on."""
    ids = {p.id for e in (program.problem.objective.expr, *program.values) for p in e.parameters()}
    return tuple(k for k, p in enumerate(program.parameters) if p.id in ids)


@dataclass(frozen=True)
class RawSolution:
    """One solve's cvxpy status name and Clarabel's primal ``u`` and dual ``z`` (empty without a
    solution)."""

    status: str
    u: np.ndarray
    z: np.ndarray


@dataclass(frozen=True)
class ClarabelProgram:
    """The conic data of a :class:`Parametrised` problem as an affine map of its parameters, and
    where its results sit in Clarabel's solution (see the module docstring)."""

    slots: tuple[tuple[int, int], ...]  # (first column in p, size) of each parameter
    constant_column: int
    tensor: sp.csr_array                # nonzeros of [A b] = tensor @ p (cvxpy's reduced tensor)
    a_nonzeros: int                     # the first a_nonzeros of them are A's, in CSC order
    a_indices: np.ndarray
    a_indptr: np.ndarray
    a_shape: tuple[int, int]
    b_rows: np.ndarray                  # rows of the remaining (b's) nonzeros
    P: sp.csc_array                     # upper triangle, as cvxpy hands it to Clarabel
    q: np.ndarray                       # when the objective has no parameters, else
    q_tensor: sp.csr_array | None       # cvxpy's tensor giving (q, offset) from p, as CSR
    cones: tuple
    program: Parametrised
    evaluated: tuple[int, ...]              # parameters in the objective or the requested values
    variable_index: tuple[np.ndarray, ...]  # lowered entries of program.problem.variables() in u
    dual_index: tuple[np.ndarray, ...]      # of program.duals in Clarabel's z

    @classmethod
    def compile(cls, program: Parametrised) -> ClarabelProgram:
        """Compile through cvxpy once (this sets the parameters and writes probe results into the
        problem's variables: compile a problem object kept for this purpose)."""
        if _MISSING_INTERNALS is not None:
            raise ValueError(f"this cvxpy lacks internals the compiler reads ({_MISSING_INTERNALS})")
        problem = program.problem
        for parameter in program.parameters:
            parameter.value = _probe_value(parameter)
        data, chain, inverse = problem.get_problem_data(cp.CLARABEL, solver_opts={})  # as Problem.solve
        cone_program = data[cvxpy_status.PARAM_PROB]
        columns = cone_program.param_id_to_col
        if set(columns) != {p.id for p in program.parameters} | {lo.CONSTANT_ID}:
            raise ValueError("cvxpy rewrites some parameters (or there are parameters not listed); "
                             "compile needs plain parameters")
        if cone_program.P is not None and sp.csc_array(cone_program.P)[:, :-1].count_nonzero():
            raise ValueError("the objective's P depends on parameters; compile does not support it")
        q_depends = sp.csc_array(cone_program.q)[:, :-1].count_nonzero() > 0
        reduced = cone_program.reduced_A
        reduced.cache(keep_zeros=False)
        indices, indptr, shape = reduced.problem_data_index
        n_var = cone_program.x.size
        b_rows = indices[indptr[n_var]:]
        if np.unique(b_rows).size != b_rows.size:
            raise ValueError("b has repeated rows in cvxpy's data; compile does not support it")
        P = data.get(cvxpy_status.P, sp.csc_array((n_var, n_var)))
        compiled = cls(
            slots=tuple((columns[p.id], p.size) for p in program.parameters),
            constant_column=columns[lo.CONSTANT_ID], tensor=reduced.reduced_mat,
            a_nonzeros=int(indptr[n_var]), a_indices=indices[:indptr[n_var]], a_indptr=indptr[:n_var + 1],
            a_shape=(shape[0], n_var), b_rows=b_rows, P=sp.triu(P).tocsc(), q=data[cvxpy_status.C],
            q_tensor=sp.csr_array(cone_program.q) if q_depends else None,
            cones=tuple(dims_to_solver_cones(data[CLARABEL.DIMS])), program=program,
            evaluated=_evaluated_parameters(program), variable_index=(), dual_index=())
        compiled._check_data(data, [p.value for p in program.parameters])
        variable_index, dual_index = compiled._result_indices(chain, inverse)
        return replace(compiled, variable_index=variable_index, dual_index=dual_index)

    def _check_data(self, data: dict, parameter_values: list) -> None:
        q, A, b = self._data(parameter_values)
        expected = data[cvxpy_status.A]
        same = (np.array_equal(q, data[cvxpy_status.C]) and np.array_equal(b, data[cvxpy_status.B])
                and all(np.array_equal(getattr(A, k), getattr(expected, k)) for k in ("indices", "indptr", "data")))
        if not same:
            raise ValueError("the compiled map does not reproduce cvxpy's conic data")

    def _result_indices(self, chain, inverse) -> tuple[tuple[np.ndarray, ...], ...]:
        """Run cvxpy's inversion on a probe solution u = (1, 2, …), z = (1, 2, …) and read which
        entries land in each variable (in the lowered form cvxpy recovers it from) and requested
        dual."""
        n_con = self.a_shape[0]
        u, z = np.arange(1.0, self.a_shape[1] + 1.0), np.arange(1.0, n_con + 1.0)
        probe = SimpleNamespace(status="Solved", x=u, z=z, s=np.zeros(n_con), obj_val=0.0,
                                solve_time=0.0, iterations=0)
        problem = self.program.problem
        problem.unpack_results(probe, chain, inverse)
        lowered = tuple(_lowered_index(v, _selection(np.asarray(v.value), u, f"the value of {v}"))
                        for v in problem.variables())
        for variable, index in zip(problem.variables(), lowered, strict=True):
            if not np.array_equal(recover_value_for_leaf(variable, u[index]), np.asarray(variable.value)):
                raise ValueError(f"the value of {variable} is not recovered from its entries of u")
        return lowered, tuple(_selection(np.asarray(c.dual_value), z, f"the dual of {c}") for c in self.program.duals)

    def _parameter_vector(self, parameter_values: Sequence) -> np.ndarray:
        p = np.zeros(self.constant_column + 1)
        p[self.constant_column] = 1.0
        for (start, size), value in zip(self.slots, parameter_values, strict=True):
            p[start:start + size] = np.ravel(value, order="F")
        return p

    def _data(self, parameter_values: Sequence) -> tuple[np.ndarray, sp.csc_array, np.ndarray]:
        """(q, A, b) as cvxpy hands them to Clarabel: cvxpy stores Au + b ∈ K, Clarabel b − Au ∈ K.
        A parametrised q is the tensor's product with p without its last entry (the objective's
        constant), as cvxpy's ``get_matrix_from_tensor`` forms it; :meth:`_check_data` compares the
        two at compilation."""
        p = self._parameter_vector(parameter_values)
        q = self.q
        if self.q_tensor is not None:
            q = (self.q_tensor @ p)[:self.a_shape[1]]
        nonzeros = self.tensor @ p
        A = sp.csc_array((-nonzeros[:self.a_nonzeros], self.a_indices, self.a_indptr), shape=self.a_shape)
        b = np.zeros(self.a_shape[0])
        b[self.b_rows] = nonzeros[self.a_nonzeros:]
        return q, A, b

    def _parameter_matrix(self, batched_values: Sequence[np.ndarray]) -> np.ndarray:
        """The parameter vectors of B problems as the columns of one (len(p), B) array: each
        parameter's values (B, *shape) flattened column-major per problem, as :meth:`_parameter_vector`."""
        runs = np.shape(batched_values[0])[0]
        p = np.zeros((self.constant_column + 1, runs))
        p[self.constant_column] = 1.0
        for (start, size), value in zip(self.slots, batched_values, strict=True):
            value = np.asarray(value, dtype=float).reshape((runs, -1) if size == 1 else np.shape(value))
            per_problem = value.transpose(0, *range(value.ndim - 1, 0, -1)).reshape(runs, size)
            p[start:start + size] = per_problem.T
        return p

    def solve_raw_batch(self, batched_values: Sequence[np.ndarray]) -> list[RawSolution]:
        """B problems, each by a new Clarabel solver with default settings, their data formed at
        once: ``batched_values`` holds each parameter's values for all B problems (a leading axis),
        in the order of :attr:`Parametrised.parameters`. The data of problem b are those
        :meth:`solve` forms for its values alone (the tensor's product with the parameter vectors
        as columns adds each row's terms in the same order) and the solve is a function of them alone.
        Returns cvxpy's status name and Clarabel's u and z (empty when it reports no solution), for
        callers that read their entries themselves (:attr:`dual_index`)."""
        p = self._parameter_matrix(batched_values)
        nonzeros = np.ascontiguousarray((self.tensor @ p).T)              # (B, nnz)
        q = self.q if self.q_tensor is None else None
        A = sp.csc_array((-nonzeros[0, :self.a_nonzeros], self.a_indices, self.a_indptr), shape=self.a_shape)
        settings = clarabel.DefaultSettings()
        settings.verbose = False
        out = []
        for b in range(p.shape[1]):
            A.data = -nonzeros[b, :self.a_nonzeros]  # the same pattern for every problem: only the values change
            rhs = np.zeros(self.a_shape[0])
            rhs[self.b_rows] = nonzeros[b, self.a_nonzeros:]
            linear = q if q is not None else (self.q_tensor @ p[:, b])[:self.a_shape[1]]
            result = clarabel.DefaultSolver(self.P, linear, A, rhs, list(self.cones), settings).solve()
            status = CLARABEL.STATUS_MAP.get(str(result.status), cvxpy_status.SOLVER_ERROR)
            present = status in cvxpy_status.SOLUTION_PRESENT
            out.append(RawSolution(status, np.asarray(result.x) if present else np.zeros(0),
                                   np.asarray(result.z) if present else np.zeros(0)))
        return out

    def solve(self, parameter_values: Sequence) -> ConicSolution:
        """One solve by a new Clarabel solver with default settings; parameter values in the order
        of :attr:`Parametrised.parameters`. Raises SolverError when Clarabel reports a failure.

        As cvxpy does, the variables are recovered from their entries of Clarabel's u, and the
        objective value and the requested values are the problem's expressions evaluated at them
        (this writes the variables, and the parameters those depend on, of the compiled problem,
        which belongs to this program)."""
        q, A, b = self._data(parameter_values)
        settings = clarabel.DefaultSettings()
        settings.verbose = False
        result = clarabel.DefaultSolver(self.P, q, A, b, list(self.cones), settings).solve()
        status = CLARABEL.STATUS_MAP.get(str(result.status), cvxpy_status.SOLVER_ERROR)
        if status not in cvxpy_status.SOLUTION_PRESENT:
            return _solution(status, None, (), ())
        u, z = np.asarray(result.x), np.asarray(result.z)
        problem = self.program.problem
        for variable, index in zip(problem.variables(), self.variable_index, strict=True):
            variable.save_value(recover_value_for_leaf(variable, u[index]))  # e.g. projects nonneg
        for k in self.evaluated:
            self.program.parameters[k].value = parameter_values[k]
        return _solution(status, problem.objective.value, [e.value for e in self.program.values],
                         [z[i] for i in self.dual_index])
