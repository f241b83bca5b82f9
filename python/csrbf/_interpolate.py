"""csrbf.Interpolator: scattered-data interpolation by Wendland's compactly supported radial basis
functions, in the shape of ``scipy.interpolate.RBFInterpolator``.

This module checks the arguments (messages that name the argument, its shape and the first bad
element), shapes the results and pickles; the fit and the evaluation are ``csrbf._core``'s (C++,
without the GIL). Values of any trailing shape are fitted as P x V; float32 values give float32
results.
"""

from __future__ import annotations

import operator

import numpy as np

from . import _core

# typing, numpy.typing and inspect cost 20 ms of `import csrbf`, which is 4 ms without them: they are
# imported where a type checker or help() asks (annotations are text: PEP 563).
TYPE_CHECKING = False
if TYPE_CHECKING:
    from typing import Any, Dict, List, Optional, Tuple, Union

    import numpy.typing as npt

    FloatArray = npt.NDArray[np.floating[Any]]

__all__ = ["Interpolator"]

_GIB = float(1 << 30)
#: The version of the state that pickles carry (1 was a 12-tuple, still read).
_STATE_VERSION = 2
_KEYWORDS = ("radius", "kernel", "degree", "smoothing", "neighbors", "levels", "method", "memory_limit", "threads",
             "solver")
_SCIPY_KERNELS = ("thin_plate_spline", "gaussian", "multiquadric")
_DTYPES = (np.dtype(np.float64), np.dtype(np.float32))  # the results' dtype, by "single"


def _type_name(obj: object) -> str:
    return type(obj).__name__


def _shortest(v: float) -> str:
    """The shortest text that reads back as v, without Python's trailing '.0'."""
    text = repr(float(v))
    return text[:-2] if text.endswith(".0") else text


def _real_array(obj: Any, what: str) -> np.ndarray:
    """obj as a numpy array of real numbers (read in place where it is one), or TypeError naming it."""
    if isinstance(obj, np.ndarray):
        a = obj
    else:
        try:
            a = np.asarray(obj)
        except (ValueError, TypeError):
            raise TypeError(f"{what} must be an array of numbers, got a {_type_name(obj)} that numpy cannot make one "
                            "of (ragged, or not numbers)") from None
    if a.dtype.kind not in "fiub":
        raise TypeError(f"{what} must hold real numbers (float64 or float32), got dtype {a.dtype}")
    if a.dtype.kind == "f" and a.dtype.itemsize > 8:
        raise TypeError(f"{what} has dtype {a.dtype}, which float64 cannot hold exactly; convert it to float64 first")
    return a


def _check_finite(a: np.ndarray, what: str, rule: str) -> None:
    """ValueError naming the first element of a that is not finite, by its index in a's own shape."""
    finite = np.isfinite(a)
    if finite.all():
        return
    index = np.unravel_index(int(np.argmin(finite.reshape(-1))), a.shape)
    text = ", ".join(str(int(i)) for i in index)
    raise ValueError(f"{what}[{text}] is {float(a[index]):g} ({rule})")


def _text(obj: Any, what: str, expected: str) -> str:
    """A keyword argument's text, lower case (names are matched in any case, as the CLI's are)."""
    if not isinstance(obj, str):
        raise TypeError(f"{what} must be {expected}, got a {_type_name(obj)}")
    return obj.lower()


def _number(obj: Any, what: str, expected: str) -> float:
    """A real number (a Python or numpy number, not a bool or a string)."""
    if isinstance(obj, (bool, np.bool_, str)) or not hasattr(obj, "__float__"):
        raise TypeError(f"{what} must be {expected}, got a {_type_name(obj)}")
    try:
        return float(obj)
    except OverflowError:
        raise ValueError(f"{what} must be {expected}, got {obj!r:.40}, beyond a float") from None


def _integer(obj: Any, what: str, expected: str) -> int:
    """An integer (a Python or numpy integer, not a bool or a float)."""
    if isinstance(obj, (bool, np.bool_)) or not hasattr(obj, "__index__"):
        shown = f" ({obj!r})" if hasattr(obj, "__float__") else ""
        raise TypeError(f"{what} must be {expected}, got a {_type_name(obj)}{shown}")
    return operator.index(obj)


def _name(kind: str, obj: Any) -> str:
    """The canonical name of a kernel or solver given in any case or by its alias."""
    parse, listed = _core._names[kind]
    text = _text(obj, kind, "one of " + listed)
    name = parse(text)
    if name is None:
        hint = (" (SciPy's global kernels; csrbf's are Wendland's compactly supported ones)"
                if kind == "kernel" and text in _SCIPY_KERNELS else "")
        raise ValueError(f"{kind} must be one of {listed}, got '{obj}'{hint}")
    return str(name)


class _Options:
    """The checked keyword arguments of Interpolator (None: the default)."""

    def __init__(self, radius: Any, kernel: Any, degree: Any, neighbors: Any, levels: Any, method: Any,
                 memory_limit: Any, threads: Any, solver: Any) -> None:
        self.radius = 0.0  # automatic
        if radius is not None and not (isinstance(radius, str) and _text(radius, "radius", "") == "auto"):
            if isinstance(radius, str):
                raise ValueError(f"radius must be a positive number or 'auto', got '{radius}'")
            r = _number(radius, "radius", "a positive number or 'auto'")
            if not (1e-150 <= r <= 1e150):
                raise ValueError("radius must be a positive finite number (within [1e-150, 1e150]) or 'auto', got "
                                 f"{radius!r}")
            self.radius = r
        self.kernel = "c2" if kernel is None else _name("kernel", kernel)
        self.degree = -1
        if degree is not None:  # None: the default, as SciPy's
            d = _integer(degree, "degree", "-1 (none), 0 or 1")
            if d not in (-1, 0, 1):
                raise ValueError(f"degree must be -1 (none), 0 or 1, got {d}")
            self.degree = d
        self.neighbors = 0.0  # the default for the levels
        if neighbors is not None:
            n = _number(neighbors, "neighbors", "a positive number")
            if not 0 < n <= 1e9:
                raise ValueError(f"neighbors must be a positive number (at most 1e9), got {neighbors!r}")
            if self.radius > 0:  # it chooses the automatic radius: beside a given radius it would be ignored
                raise ValueError(f"neighbors={neighbors!r} chooses the automatic radius, but "
                                 f"radius={_shortest(self.radius)} is given: give one of them (radius='auto' with "
                                 "neighbors)")
            self.neighbors = n
        self.levels = self._levels(levels, method)
        self.memory_limit = 4.0
        if memory_limit is not None:
            gib = _number(memory_limit, "memory_limit", "a number of GiB")
            if not (0 < gib <= 1e6):
                bytes_hint = f" (bytes? that is {gib / _GIB:.3g} GiB)" if gib > 1e6 else ""
                raise ValueError("memory_limit is in GiB, as csrbf's --memory-limit: a number in (0, 1e6], got "
                                 f"{memory_limit!r}{bytes_hint}")
            self.memory_limit = gib
        self.threads = 0  # TBB's default: every core
        if threads is not None:
            t = _integer(threads, "threads", "a positive integer")
            if not 1 <= t <= 4096:
                raise ValueError(f"threads must be a positive integer (at most 4096), got {t}")
            self.threads = t
        self.solver = "auto" if solver is None else _name("solver", solver)

    @staticmethod
    def _levels(levels: Any, method: Any) -> int:
        """1: single scale; n > 1: that many levels; 0: automatic."""
        name = None
        if method is not None:
            name = _text(method, "method", "'single' or 'multiscale'")
            if name not in ("single", "multiscale"):
                raise ValueError(f"method must be 'single' or 'multiscale', got '{method}'")
        if levels is None:
            return 0 if name == "multiscale" else 1
        most = _core._MAX_LEVELS
        expected = f"an integer 1..{most} or 'auto'"
        if isinstance(levels, str):
            if _text(levels, "levels", expected) != "auto":
                raise ValueError(f"levels must be {expected}, got '{levels}'")
            count = 0
        else:
            count = _integer(levels, "levels", expected)
            if not 1 <= count <= most:
                raise ValueError(f"levels must be within 1..{most} or 'auto', got {count}")
        if name == "single" and count != 1:
            raise ValueError(f"method='single' with levels={levels}: several levels are the multiscale method (give "
                             "levels alone, or method='multiscale')")
        if name == "multiscale" and count == 1:
            raise ValueError("method='multiscale' with levels=1: one level is the single-scale method")
        return count


def _data(points: Any, values: Any) -> Tuple[np.ndarray, np.ndarray, Tuple[int, ...], bool]:
    """points as (P, D) float64 and values as (P, V) float64 (read in place where they are), checked; the
    values' trailing shape and whether they are float32."""
    pts = _real_array(points, "points")
    most = _core._MAX_DIMENSION
    if pts.ndim != 2:
        hint = " (1-D data: points[:, None])" if pts.ndim == 1 else ""
        raise ValueError(f"points must have shape (P, D), D = 1, 2 or 3, got {pts.shape}{hint}")
    p, d = pts.shape
    if d > most and 1 <= p <= most:
        raise ValueError(f"points must have shape (P, D) with D = 1, 2 or 3, got {pts.shape}: is it transposed? "
                         f"(points.T has shape {(d, p)})")
    if d == 0:
        raise ValueError(f"points must have shape (P, D) with D = 1, 2 or 3, got {pts.shape}: no coordinates")
    if not 1 <= d <= most:
        raise ValueError(f"points must have shape (P, D) with D = 1, 2 or 3, got {pts.shape}: csrbf's Wendland "
                         "kernels are positive definite only up to 3 dimensions (built for R^3); in higher dimensions "
                         "the system can be singular")
    if p == 0:
        raise ValueError(f"points is empty (shape {pts.shape})")
    vals = _real_array(values, "values")
    if vals.ndim < 1 or vals.shape[0] != p:
        raise ValueError(f"values must have shape (P, ...) with P = {p} (one row a point), got {vals.shape}")
    if vals.size == 0:
        raise ValueError(f"values has no value a point (shape {vals.shape})")
    _check_finite(pts, "points", "must be finite")
    _check_finite(vals, "values", "must be finite")
    pts = np.ascontiguousarray(pts, dtype=np.float64)
    flat = np.ascontiguousarray(vals, dtype=np.float64).reshape(p, -1)
    return pts, flat, tuple(int(e) for e in vals.shape[1:]), vals.dtype == np.float32


def _smoothing(smoothing: Any, p: int) -> np.ndarray:
    """lambda as an empty array (0 everywhere: interpolation), one value, or one a point."""
    if smoothing is None:
        return np.zeros(0)
    sm = _real_array(smoothing, "smoothing")
    if sm.dtype.kind == "b":
        raise TypeError("smoothing must be a number >= 0 or an array of them, got booleans")
    if not (sm.ndim == 0 or (sm.ndim == 1 and sm.shape[0] == p)):
        raise ValueError(f"smoothing must be a number or an array of shape ({p},), got {sm.shape}")
    flat = np.ascontiguousarray(sm, dtype=np.float64).reshape(-1)
    bad = ~(np.isfinite(flat) & (flat >= 0))
    if bad.any():
        i = int(np.argmax(bad))
        where = f"[{i}]" if sm.ndim else ""
        raise ValueError(f"smoothing{where} is {flat[i]:g} (must be finite and >= 0)")
    return np.zeros(0) if not flat.any() else flat


def _into_float32(result: np.ndarray, computed: np.ndarray, what: str, one: bool) -> None:
    """result (float32) = computed (float64), or ValueError where a number is beyond float32."""
    big = np.abs(computed) > np.finfo(np.float32).max
    if big.any():
        index = np.unravel_index(int(np.argmax(big.reshape(-1))), computed.shape)
        at = "" if one else f" at x[{int(index[0])}]"
        raise ValueError(f"the interpolant's {what}{at} is {float(computed[index]):g}, beyond float32 (the values' "
                         "dtype): evaluate an interpolant of float64 values")
    result[...] = computed


def _output(out: Any, shape: Tuple[int, ...], dtype: np.dtype) -> np.ndarray:
    """The result's array: `out` checked (shape, dtype, C-contiguous, writeable), or a new one."""
    if out is None:
        return np.empty(shape, dtype)
    if not isinstance(out, np.ndarray):
        raise TypeError(f"out must be a numpy array, got a {_type_name(out)}")
    problem = None
    if out.dtype != dtype:
        problem = f"its dtype is {out.dtype}"
    elif out.shape != shape:
        problem = f"its shape is {out.shape}"
    elif not out.flags.c_contiguous:
        problem = "it is not C-contiguous"
    elif not out.flags.writeable:
        problem = "it is read-only"
    if problem:
        raise ValueError(f"out must be a writeable C-contiguous {shape} {dtype} array: {problem}")
    return out


class _Signature(type):
    """help() and inspect show Interpolator's parameters (its __init__'s), not __new__'s (*args, **kwargs)."""

    @property
    def __signature__(cls):  # type: ignore[no-untyped-def]
        import inspect

        init = inspect.signature(cls.__init__)
        return init.replace(parameters=list(init.parameters.values())[1:])


class Interpolator(metaclass=_Signature):
    """Interpolation of scattered data by compactly supported radial basis functions (Wendland).

    The compact-support counterpart of ``scipy.interpolate.RBFInterpolator``: each basis function
    reaches only ``radius`` from its point, so the system is sparse and evaluation touches only the
    points within ``radius`` of x.

        s(x) = sum_i alpha_i phi(|x - x_i| / R) + p(x),   s(x_i) + lambda_i alpha_i = f_i

    Parameters
    ----------
    points : array_like, shape (P, D)
        The data sites, D = 1, 2 or 3 (the Wendland kernels are positive definite up to 3-D).
    values : array_like, shape (P, ...)
        The data values: any trailing shape (scalars, vectors, tensors). float32 values give float32
        results; anything else float64.
    radius : float or 'auto', optional
        The radius of support R in the points' units. 'auto' (default) picks R so that a point has
        ``neighbors`` others within R on average; ``stats`` says what was chosen. With several levels,
        the radius of the finest level (the thinned levels have 4 R, 8 R, ...).
    kernel : {'c0', 'c2', 'c4', 'c6'}, optional
        The Wendland function (smoothness C0 to C6). Default 'c2'.
    degree : {-1, 0, 1}, optional
        The polynomial: -1 none (default; strictly local: s = 0 farther than R from every point, or
        with several levels farther than the coarsest level's radius from every point of that level),
        0 a constant, 1 linear (as SciPy's thin-plate spline: data with an offset or a trend, and
        points evaluated between sparse data, want 1). None is the default.
    smoothing : float or array_like of shape (P,), optional
        lambda >= 0 added to the diagonal: 0 interpolates, larger values smooth noisy data. The
        diagonal is phi(0) = 1 (or 3 for C4), so lambda is relative to 1, not to SciPy's kernel scale.
    neighbors : float, optional
        The mean number of other points within the automatic radius (default 40; 50 with several
        levels). Not SciPy's ``neighbors``: compact support is the locality, nothing is looked up a
        query. With several levels, the thinned levels have about this many; the finest (every point)
        half the automatic radius, about neighbors / 2^D.
    levels : int or 'auto', optional
        1 (default): one radius. n > 1: the multiscale method (Floater & Iske 1996): nested subsets of
        the points, each level fitting what the coarser ones left with half their radius, the last at
        every point; fewer where a coarser level would have fewer than 2 points (``levels`` says how
        many). 'auto': levels until the coarsest has at most 250 points (at most 8).
    method : {'single', 'multiscale'}, optional
        'multiscale' is ``levels='auto'``; 'single' is ``levels=1``.
    memory_limit : float, optional
        The most memory the fit may take, in GiB (default 4); beyond it MemoryError, before allocating.
    threads : int, optional
        Threads for fit and evaluation (default: all cores).
    solver : {'auto', 'envelope', 'eigen', 'cholmod', 'cg'}, optional
        The sparse solver (default 'auto').

    Raises
    ------
    ValueError
        Bad shapes or values (the message names the argument, its shape and the first bad element),
        duplicate points without smoothing, a degenerate polynomial, an ill-conditioned system.
    TypeError
        Arguments that are not arrays of real numbers.
    MemoryError
        The fit would pass ``memory_limit``.

    Examples
    --------
    >>> import numpy as np, csrbf
    >>> rng = np.random.default_rng(0)
    >>> xy = rng.random((2000, 2))
    >>> f = np.sin(3 * xy[:, 0]) * xy[:, 1]
    >>> s = csrbf.Interpolator(xy, f, neighbors=30)
    >>> float(abs(s([0.5, 0.5]) - np.sin(1.5) * 0.5)) < 1e-2
    True
    """

    __slots__ = ("_fitted", "_dimension", "_value_shape", "_single", "_threads", "_radius_auto", "_neighbors",
                 "_solver")

    def __new__(cls, *args: Any, **kwargs: Any) -> "Interpolator":
        # Positional and keyword mistakes are reported here, with what the user may have meant
        # (SciPy's names); with no arguments at all (pickle's protocol 2), an unfitted object.
        if cls is Interpolator and (args or kwargs):  # a subclass's __init__ takes what it takes
            if len(args) != 2:
                rest = "; radius and the rest are keyword-only" if len(args) > 2 else ""
                raise TypeError("Interpolator() takes points and values as its two positional arguments, got "
                                f"{len(args)}{rest}")
            for name in kwargs:
                if name not in _KEYWORDS:
                    hint = ""
                    if name == "epsilon":
                        hint = " (SciPy's shape parameter: csrbf's kernels have a radius of support, radius=)"
                    elif name in ("points", "values"):
                        hint = " (points and values are positional)"
                    raise TypeError(f"Interpolator() got an unexpected keyword argument '{name}'{hint}; it takes "
                                    "radius, kernel, degree, smoothing, neighbors, levels, method, memory_limit, "
                                    "threads and solver")
        return super().__new__(cls)

    def __init__(
        self,
        points: npt.ArrayLike,
        values: npt.ArrayLike,
        /,
        *,
        radius: Union[float, str, None] = "auto",
        kernel: Optional[str] = "c2",
        degree: Optional[int] = None,
        smoothing: Union[float, npt.ArrayLike, None] = 0.0,
        neighbors: Optional[float] = None,
        levels: Union[int, str, None] = None,
        method: Optional[str] = None,
        memory_limit: Optional[float] = 4.0,
        threads: Optional[int] = None,
        solver: Optional[str] = "auto",
    ) -> None:
        o = _Options(radius, kernel, degree, neighbors, levels, method, memory_limit, threads, solver)
        pts, vals, value_shape, single = _data(points, values)
        sm = _smoothing(smoothing, len(pts))
        try:
            fitted = _core._fit_interpolator(pts, vals, sm, o.radius, o.kernel, o.degree, o.neighbors, o.levels,
                                             o.memory_limit * _GIB, o.threads, o.solver)
        except MemoryError as e:
            raise MemoryError(f"{e} [csrbf.Interpolator: memory_limit is {o.memory_limit:.3g} GiB; raise it, or ask "
                              "for fewer neighbors or a smaller radius]") from None
        self._fitted = fitted
        self._dimension = int(fitted.dimension)
        self._value_shape = value_shape
        self._single = single
        self._threads = o.threads
        self._radius_auto = o.radius == 0
        if o.neighbors > 0:
            self._neighbors = o.neighbors
        else:
            several = len(fitted.levels(False)) > 1
            self._neighbors = _core._MULTISCALE_NEIGHBORS if several else _core._DEFAULT_NEIGHBORS
        self._solver = o.solver

    # -- evaluation -------------------------------------------------------------------------------

    def _fit(self) -> Any:
        """The fitted interpolant, or ValueError for an object whose __init__ was not called or failed."""
        fitted = getattr(self, "_fitted", None)
        if fitted is None:
            raise ValueError("this csrbf.Interpolator was never fitted (its __init__ was not called, or failed)")
        return fitted

    def _query(self, x: Any) -> Tuple[np.ndarray, bool]:
        """The evaluation points as (Q, D) and whether one point (D,) was given (of a fitted object)."""
        d = self._dimension
        a = _real_array(x, "x")
        if (a.ndim == 1 and a.shape[0] == d) or (a.ndim == 0 and d == 1):
            return a.reshape(1, d), True
        if a.ndim != 2 or a.shape[1] != d:
            raise ValueError(f"x must have shape (Q, {d}) or ({d},), for this interpolant of {d}-D points, got "
                             f"{a.shape}")
        return a, False

    def __call__(self, x: npt.ArrayLike, *, out: Optional[FloatArray] = None) -> FloatArray:
        """Evaluates the interpolant.

        Parameters
        ----------
        x : array_like, shape (Q, D) or (D,)
            The points.
        out : numpy.ndarray, optional
            Where to write the result: C-contiguous, writeable, of the result's shape and dtype.

        Returns
        -------
        numpy.ndarray, shape (Q, ...) or (...)
            The values' trailing shape, in the values' dtype.

        Examples
        --------
        >>> import numpy as np, csrbf
        >>> s = csrbf.Interpolator(np.eye(3), np.arange(3.0), radius=2.0)
        >>> s(np.eye(3)).round(12).tolist()
        [0.0, 1.0, 2.0]
        """
        fitted = self._fit()
        q, one = self._query(x)
        shape = (() if one else (len(q),)) + self._value_shape
        result = _output(out, shape, _DTYPES[self._single])
        if self._single and q.dtype == np.float32:
            fitted.evaluate(np.ascontiguousarray(q), result, self._threads)  # float32 throughout
        elif not self._single:
            fitted.evaluate(np.ascontiguousarray(q, dtype=np.float64), result, self._threads)
        else:  # float32 values at float64 points: evaluated in double
            staging = np.empty(shape, np.float64)
            fitted.evaluate(np.ascontiguousarray(q, dtype=np.float64), staging, self._threads)
            _into_float32(result, staging, "value", one)
        return result

    def gradient(self, x: npt.ArrayLike, *, out: Optional[FloatArray] = None) -> FloatArray:
        """The derivatives of the interpolant.

        Parameters
        ----------
        x : array_like, shape (Q, D) or (D,)
        out : numpy.ndarray, optional

        Returns
        -------
        numpy.ndarray, shape (Q, ..., D) or (..., D)
            ``g[q, ..., d]`` is the derivative of the value ``[...]`` along coordinate d at x[q].

        Examples
        --------
        >>> import numpy as np, csrbf
        >>> x = np.linspace(0, 1, 50)[:, None]
        >>> s = csrbf.Interpolator(x, 2 * x[:, 0], radius=0.2, degree=1)
        >>> round(float(s.gradient([0.5])[0]), 6)
        2.0
        """
        fitted = self._fit()
        q, one = self._query(x)
        shape = (() if one else (len(q),)) + self._value_shape + (fitted.dimension,)
        result = _output(out, shape, self.dtype)
        g = fitted.gradient(np.ascontiguousarray(q, dtype=np.float64), self._threads).reshape(shape)
        if self._single:
            _into_float32(result, g, "derivative", one)
        else:
            result[...] = g
        return result

    # -- what was fitted --------------------------------------------------------------------------

    @property
    def stats(self) -> Dict[str, Any]:
        """What the fit chose and did: the radius (and whether it was automatic), the mean neighbours, the
        solver, its iterations, the largest relative residual of the system, and each level's figures.

        Examples
        --------
        >>> import numpy as np, csrbf
        >>> s = csrbf.Interpolator(np.random.default_rng(1).random((500, 2)), np.ones(500), neighbors=20)
        >>> round(s.stats['neighbors'])
        20
        """
        fitted = self._fit()
        levels: List[Dict[str, Any]] = fitted.levels(False)
        finest = levels[-1]
        return {
            "points": fitted.size,
            "dimension": fitted.dimension,
            "values": fitted.value_count,
            "radius": finest["radius"],
            "radius_auto": self._radius_auto,
            "target_neighbors": self._neighbors,
            "neighbors": finest["neighbors"],
            "solver": finest["solver"],
            "iterations": finest["iterations"],
            "residual": max(0.0, *(level["residual"] for level in levels)),
            "levels": levels,
            "seconds_fit": fitted.seconds_fit,
        }

    @property
    def dimension(self) -> int:
        """D, the dimension of the points"""
        self._fit()
        return self._dimension

    @property
    def value_shape(self) -> Tuple[int, ...]:
        """The trailing shape of the values"""
        self._fit()
        return self._value_shape

    @property
    def dtype(self) -> np.dtype:
        """The dtype of the results (the values')"""
        self._fit()
        return _DTYPES[self._single]

    @property
    def kernel(self) -> str:
        """The Wendland kernel"""
        return str(self._fit().kernel)

    @property
    def degree(self) -> int:
        """The polynomial's degree"""
        return int(self._fit().degree)

    @property
    def radius(self) -> float:
        """The radius of support (of the finest level)"""
        return float(self._fit().levels(False)[-1]["radius"])

    @property
    def levels(self) -> int:
        """The number of levels (1: single scale)"""
        return len(self._fit().levels(False))

    def __len__(self) -> int:
        return int(self._fit().size)

    def __repr__(self) -> str:
        fitted = getattr(self, "_fitted", None)
        if fitted is None:
            return "csrbf.Interpolator(not fitted)"
        levels = fitted.levels(False)
        finest = levels[-1]
        shape = self._value_shape
        shape_text = "(" + ", ".join(str(e) for e in shape) + ("," if len(shape) == 1 else "") + ")"
        return (f"csrbf.Interpolator(points={fitted.size}, dimension={fitted.dimension}, values={shape_text} "
                f"{'float32' if self._single else 'float64'}, kernel='{fitted.kernel}', degree={fitted.degree}, "
                f"levels={len(levels)}, radius={finest['radius']:g}{' (auto)' if self._radius_auto else ''}, "
                f"neighbors={finest['neighbors']:g})")

    # -- pickling ---------------------------------------------------------------------------------

    def __getstate__(self) -> Dict[str, Any]:
        """The fit as plain data: each level's points and coefficients (no refit on loading)."""
        fitted = self._fit()
        state = {
            "format": "csrbf.Interpolator",
            "version": _STATE_VERSION,
            "dimension": fitted.dimension,
            "value_shape": self._value_shape,
            "dtype": "float32" if self._single else "float64",
            "kernel": fitted.kernel,
            "degree": fitted.degree,
            "levels": fitted.levels(True),
            "threads": self._threads,
            "radius_auto": self._radius_auto,
            "neighbors": self._neighbors,
            "solver": self._solver,
            "seconds_fit": fitted.seconds_fit,
        }
        extra = getattr(self, "__dict__", None)  # a subclass's own attributes
        if extra:
            state["attributes"] = dict(extra)
        return state

    def __setstate__(self, state: Any) -> None:
        # Every malformed state is a ValueError naming the state, whatever the part that is wrong,
        # and a state that fails leaves the object as it was.
        try:
            checked = _checked_state(_state_v2(state))
        except ValueError as e:
            if str(e).startswith("Interpolator state:"):
                raise
            raise ValueError(f"Interpolator state: malformed ({e})") from None
        except (TypeError, KeyError, IndexError, OverflowError, AttributeError) as e:
            raise ValueError(f"Interpolator state: malformed ({type(e).__name__}: {e})") from None
        (self._fitted, self._value_shape, self._single, self._threads, self._radius_auto, self._neighbors,
         self._solver, attributes) = checked
        self._dimension = int(self._fitted.dimension)
        if attributes:
            self.__dict__.update(attributes)

    def __reduce__(self) -> Tuple[Any, ...]:
        return (_restore, (self.__getstate__(), type(self)))


def _exactly(value: Any, kind: type, what: str) -> Any:
    """value if it is of exactly this type (an int is not a bool, a float not an int), else ValueError."""
    if type(value) is not kind and not (kind is float and type(value) in (int, np.float64)):
        raise ValueError(f"Interpolator state: {what} is a {_type_name(value)}, not a {kind.__name__}")
    return value


def _checked_level(level: Any, k: int) -> Dict[str, Any]:
    """A level of a state as _core._interpolator_from_levels takes it, each field checked."""
    if not isinstance(level, dict):
        raise ValueError(f"Interpolator state: levels[{k}] is a {_type_name(level)}, not a dict")
    out: Dict[str, Any] = {}
    for key in ("points", "alpha", "beta"):
        out[key] = np.ascontiguousarray(np.asarray(level[key], dtype=np.float64))
    center = tuple(float(_exactly(c, float, f"levels[{k}].center")) for c in level["center"])
    if len(center) != 3:
        raise ValueError(f"Interpolator state: levels[{k}].center has {len(center)} numbers, not 3")
    out["center"] = center
    for key in ("radius", "scale", "neighbors", "residual", "rms_before", "seconds"):
        out[key] = float(_exactly(level[key], float, f"levels[{k}].{key}"))
    iterations = _exactly(level["iterations"], int, f"levels[{k}].iterations")
    if iterations < 0:
        raise ValueError(f"Interpolator state: levels[{k}].iterations is {iterations}")
    out["iterations"] = iterations
    solver = level["solver"]
    if not isinstance(solver, str) or _core._names["solver"][0](solver) != solver:
        raise ValueError(f"Interpolator state: levels[{k}].solver is {solver!r}")
    out["solver"] = solver
    return out


def _checked_state(s: Dict[str, Any]) -> Tuple[Any, ...]:
    """The parts of an Interpolator from a state of this version, every field checked."""
    if s.get("format") != "csrbf.Interpolator" or type(s.get("version")) is not int or s["version"] != _STATE_VERSION:
        raise ValueError("Interpolator state: not a state of this version of csrbf")
    value_shape = tuple(_exactly(e, int, "value_shape") for e in s["value_shape"])
    if len(value_shape) > 32:
        raise ValueError("Interpolator state: value shape of too many dimensions")
    count = 1
    for e in value_shape:
        count *= e
        if not 1 <= e <= 1 << 40 or count > 1 << 40:
            raise ValueError(f"Interpolator state: value shape {value_shape}")
    threads = _exactly(s["threads"], int, "threads")
    if not 0 <= threads <= 4096:
        raise ValueError(f"Interpolator state: threads {threads}")
    if s["dtype"] not in ("float32", "float64"):
        raise ValueError(f"Interpolator state: dtype {s['dtype']!r}")
    radius_auto = _exactly(s["radius_auto"], bool, "radius_auto")
    neighbors = float(_exactly(s["neighbors"], float, "neighbors"))
    if not 0 < neighbors <= 1e9:
        raise ValueError(f"Interpolator state: neighbors {neighbors}")
    solver = s["solver"]
    if not isinstance(solver, str) or _core._names["solver"][0](solver) != solver:
        raise ValueError(f"Interpolator state: solver {solver!r}")
    if not isinstance(s["levels"], list):
        raise ValueError(f"Interpolator state: levels is a {_type_name(s['levels'])}, not a list")
    levels = [_checked_level(level, k) for k, level in enumerate(s["levels"])]
    attributes = s.get("attributes") or {}
    if not isinstance(attributes, dict):
        raise ValueError(f"Interpolator state: attributes is a {_type_name(attributes)}, not a dict")
    fitted = _core._interpolator_from_levels(_exactly(s["dimension"], int, "dimension"), count,
                                             _exactly(s["kernel"], str, "kernel"),
                                             _exactly(s["degree"], int, "degree"), levels,
                                             float(_exactly(s["seconds_fit"], float, "seconds_fit")))
    return fitted, value_shape, s["dtype"] == "float32", threads, radius_auto, neighbors, solver, attributes


def _state_v2(state: Any) -> Dict[str, Any]:
    """A state of this version; a version-1 state (csrbf 0.1's 12-tuple) is read into one."""
    if isinstance(state, dict):
        return state
    if not isinstance(state, tuple) or len(state) != 12 or type(state[0]) is not int or state[0] != 1:
        raise ValueError("Interpolator state: not a state of this version of csrbf")
    (_, dimension, value_shape, single, kernel, degree, levels, threads, radius_auto, neighbors, solver,
     seconds_fit) = state
    _exactly(single, bool, "single")
    keys = ("neighbors", "solver", "iterations", "residual", "rms_before", "seconds")
    v2_levels = [dict(radius=l[0], points=l[1], alpha=l[2], beta=l[3], center=l[4], scale=l[5], **dict(zip(keys, l[6])))
                 for l in levels]
    return {"format": "csrbf.Interpolator", "version": _STATE_VERSION, "dimension": dimension,
            "value_shape": value_shape, "dtype": "float32" if single else "float64", "kernel": kernel,
            "degree": degree, "levels": v2_levels, "threads": threads, "radius_auto": radius_auto,
            "neighbors": neighbors, "solver": solver, "seconds_fit": seconds_fit}


def _restore(state: Dict[str, Any], cls: type = None) -> Interpolator:  # type: ignore[assignment]
    """An Interpolator (or an instance of its subclass cls) from its pickled state (__reduce__)."""
    if cls is None or not (isinstance(cls, type) and issubclass(cls, Interpolator)):
        if cls is not None:
            raise ValueError(f"Interpolator state: {cls!r} is not an Interpolator")
        cls = Interpolator
    s = cls.__new__(cls)
    s.__setstate__(state)
    return s
