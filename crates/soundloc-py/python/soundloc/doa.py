"""A drop-in for pyroomacoustics' ``doa`` module: ``MUSIC``, ``NormMUSIC`` and ``SRP``
(SRP-PHAT) with pyroomacoustics' constructor and ``locate_sources``, computed by soundloc.

    import soundloc.doa
    doa = soundloc.doa.algorithms["MUSIC"](L, fs, nfft, c=343.0, num_src=2)
    doa.locate_sources(X, freq_range=[300.0, 3500.0])    # X: (M, nfft/2+1, snapshots)
    doa.azimuth_recon, doa.grid.values

Same conventions as pyroomacoustics: ``L`` is (2 or 3, M) microphone positions in metres;
``azimuth`` (radians from +x toward +y) and ``colatitude`` (radians from +z) define the
grid; ``dim=2`` searches the plane, ``dim=3`` the Cartesian product of azimuth ×
colatitude (or, without them, a sphere of ``n_grid`` points). Far field only (plane
waves): a source distance is not modelled. ``grid.values`` is the spatial spectrum in
pyroomacoustics' own scale (MUSIC: mean over bins of 1/aᴴ(I − EsEsᴴ)a; NormMUSIC: each
bin normalised to a maximum of 1 first; SRP: mean over bins and microphone pairs of
Re aᴴ R̃ a with R̃ the phase-transformed correlation), so existing plotting code works.
Peaks: local maxima of the grid (left/right on a circle, the 6 nearest directions on a
sphere); ``src_idx`` / ``azimuth_recon`` hold the ``num_src`` strongest in
pyroomacoustics' order (its ``find_peaks``: weakest of them first, strongest last).
After ``locate_sources`` also ``freq_bins``, ``freq_hz``, ``num_freq``, ``num_snap`` and
``grid.cartesian`` / ``grid.spherical`` / ``grid.set_values`` as pyroomacoustics has them;
not provided: CSSM, WAVES, TOPS, FRIDA, per-bin ``Pssl`` and the plotting helpers
(``polar_plt_dirac``, ``grid.plot``: plot ``grid.values`` with matplotlib directly).
"""

import warnings
from types import SimpleNamespace

import numpy as np

from ._native import FramesLocalizer as _Frames

__all__ = ["MUSIC", "NormMUSIC", "SRP", "algorithms"]

# Plane waves: sources this far away (metres) differ from a plane wave by far less than
# single-precision rounding for arrays up to a metre across.
_FAR_M = 1.0e4


class _Grid:
    """The search grid with pyroomacoustics' attribute names."""

    def __init__(self, azimuth, colatitude):
        self.azimuth = np.asarray(azimuth, dtype=float)
        self.colatitude = None if colatitude is None else np.asarray(colatitude, dtype=float)
        col = np.full_like(self.azimuth, np.pi / 2) if self.colatitude is None else self.colatitude
        self.x = np.sin(col) * np.cos(self.azimuth)
        self.y = np.sin(col) * np.sin(self.azimuth)
        self.z = np.cos(col)
        self.n_points = self.azimuth.size
        self.values = np.zeros(self.n_points)
        self.dim = 2 if self.colatitude is None else 3

    @property
    def cartesian(self):
        """Unit vectors as pyroomacoustics stores them: (2, N) on a circle, (3, N) else."""
        return np.stack([self.x, self.y] if self.dim == 2 else [self.x, self.y, self.z])

    @property
    def spherical(self):
        """(1, N) azimuths on a circle, (2, N) azimuths and colatitudes else (radians)."""
        return np.stack([self.azimuth] if self.dim == 2 else [self.azimuth, self.colatitude])

    def set_values(self, vals):
        vals = np.asarray(vals, dtype=float)
        if vals.shape != (self.n_points,):
            raise ValueError(f"values must be ({self.n_points},), got shape {vals.shape}")
        self.values = vals

    def points(self):
        return np.stack([self.x, self.y, self.z], axis=1)


class _DOA:
    _algorithm = "sevd"
    _normalize = False

    def __init__(self, L, fs, nfft, c=343.0, num_src=1, mode="far", r=None, azimuth=None,
                 colatitude=None, n_grid=None, dim=2, device="auto", precision="f32", **kwargs):
        L = np.asarray(L, dtype=float)
        if L.ndim != 2 or L.shape[0] not in (2, 3):
            raise ValueError(f"L must be (2 or 3, M) microphone positions, got shape {L.shape}")
        if mode != "far":
            raise ValueError("soundloc.doa models plane waves only (mode='far')")
        if dim not in (2, 3):
            raise ValueError("The dimension must be 2 or 3.")
        if nfft % 2:
            raise ValueError("Signal length must be even.")
        if not (np.isfinite(fs) and int(fs) >= 1):
            raise ValueError(f"fs must be a positive sampling rate in Hz, got {fs}")
        if int(nfft) < 4:
            raise ValueError(f"nfft must be an even FFT length of at least 4, got {nfft}")
        if not (np.isfinite(c) and c > 0):
            raise ValueError(f"c must be a positive speed of sound in m/s, got {c}")
        self._algorithm_checks(int(num_src), L.shape[1])
        if n_grid is not None and int(n_grid) < 1:
            raise ValueError(f"n_grid must be at least 1, got {n_grid}")
        self.L = L if L.shape[0] == 3 else np.vstack([L, np.zeros((1, L.shape[1]))])
        self.M = L.shape[1]
        self.fs, self.nfft, self.c = int(fs), int(nfft), float(c)
        self.num_src = self._num_src = int(num_src)
        self.max_bin = self.nfft // 2 + 1
        self.dim = dim
        self.device, self.precision = device, precision
        if azimuth is None:
            if dim == 2:
                n = 360 if n_grid is None else int(n_grid)
                azimuth = np.linspace(0, 2 * np.pi, n, endpoint=False)
            else:
                n = 180 * 90 if n_grid is None else int(n_grid)
                # The Fibonacci sphere of pyroomacoustics' GridSphere, point for point, and
                # its angles as it computes them (azimuth in (−π, π]).
                offset = 2.0 / n
                z = (np.arange(n) * offset - 1) + offset / 2
                rho = np.sqrt(1.0 - z ** 2)
                phi = np.arange(n) * (np.pi * (3.0 - np.sqrt(5.0)))
                x, y = np.cos(phi) * rho, np.sin(phi) * rho
                self.grid = _Grid(np.arctan2(y, x), np.arctan2(np.linalg.norm(np.stack([x, y]), axis=0), z))
        if not hasattr(self, "grid"):
            azimuth = np.asarray(azimuth, dtype=float)
            if azimuth.ndim != 1 or azimuth.size == 0:
                raise ValueError(f"Azimuth must be a non-empty 1D ndarray, got shape {azimuth.shape}")
            if colatitude is not None:
                colatitude = np.asarray(colatitude, dtype=float)
                if colatitude.ndim != 1 or colatitude.size == 0:
                    raise ValueError(
                        f"Colatitude must be a non-empty 1D ndarray, got shape {colatitude.shape}")
            if dim == 2:
                self.grid = _Grid(azimuth, None)
            elif colatitude is None:
                self.grid = _Grid(azimuth, np.full_like(azimuth, np.pi / 2))
            else:
                A, C = np.meshgrid(np.unique(azimuth), np.unique(colatitude))
                self.grid = _Grid(A.flatten(), C.flatten())
        self.azimuth_recon = None
        self.colatitude_recon = None
        self.src_idx = None
        self.freq_bins = None
        self.freq_hz = None
        self.num_freq = None
        self.num_snap = None
        self._native = _Frames(
            # Far from the array's own centre, not the coordinates' origin: an array at room
            # or survey coordinates keeps plane waves (pyroomacoustics' far field).
            np.ascontiguousarray(self.L.T),
            np.ascontiguousarray(self.L.mean(axis=1)[None, :] + self.grid.points() * _FAR_M),
            self.fs, self.nfft, self.c, self._algorithm, self._normalize, False, precision, device,
        )

    def locate_sources(self, X, num_src=None, freq_range=(500.0, 4000.0), freq_bins=None, freq_hz=None):
        """Localize from X, the rfft of each microphone: (M, nfft/2 + 1, snapshots)."""
        if num_src is not None:
            self._algorithm_checks(int(num_src), self.M)
            self._num_src = int(num_src)
        X = np.asarray(X)
        if not np.iscomplexobj(X):
            # pyroomacoustics takes it too, but a real array has lost the STFT's phase: the
            # directions come out mirror-ambiguous, so say so rather than guess silently.
            warnings.warn(
                f"X has real dtype {X.dtype}: the STFT's phase is lost and the directions are "
                "not meaningful (pass the complex STFT, e.g. pyroomacoustics.transform.stft.analysis)",
                stacklevel=2,
            )
        if (X.dtype != np.complex128 or not X.flags.aligned
                or any(st < 0 or st % X.itemsize for st in X.strides)):
            X = np.ascontiguousarray(X, dtype=np.complex128)
        if X.ndim != 3:
            raise ValueError(
                f"X must be (M, nfft/2 + 1, snapshots), got shape {X.shape}"
                + ("; for a batch, call locate_sources on each X[i]" if X.ndim == 4 else ""))
        if X.shape[0] != self.M:
            raise ValueError("Number of signals (rows) does not match the number of microphones.")
        if X.shape[1] != self.max_bin:
            raise ValueError("Mismatch in FFT length.")
        key = (tuple(np.ravel(freq_bins).tolist()) if freq_bins is not None else None,
               tuple(np.ravel(freq_hz).tolist()) if freq_hz is not None else None,
               tuple(np.ravel(freq_range).tolist()))
        if key != getattr(self, "_bins_key", None):
            self._bins = self._used_bins(freq_range, freq_bins, freq_hz)
            self._bins[0].setflags(write=False)  # shared as self.freq_bins
            self._bins_key = key
        bins, (lo, hi), weights = self._bins
        self.freq_bins = bins
        self.freq_hz = bins * float(self.fs) / float(self.nfft)
        self.num_freq = bins.size
        self.num_snap = X.shape[2]
        db, peaks = self._native.process(X, (lo, hi), weights, self._num_src)
        self.grid.values = self._scale(10.0 ** (db.astype(np.float64) / 10.0) - 1.0)
        # soundloc gives them strongest first; pyroomacoustics ascending.
        self.src_idx = np.asarray(peaks[::-1], dtype=np.int64)
        # As pyroomacoustics: num_src becomes the number of peaks found (fewer where the
        # spectrum has fewer local maxima), so loops over range(num_src) stay in bounds.
        # The next call still looks for the number asked for (the constructor's, or the
        # last num_src= given): a block with no peaks (silence) does not make every later
        # call fail on num_src=0, nor shrink MUSIC's signal subspace.
        self.num_src = len(self.src_idx)
        self.azimuth_recon = self.grid.azimuth[self.src_idx]
        if self.dim == 3:
            self.colatitude_recon = self.grid.colatitude[self.src_idx]
        return self

    def _algorithm_checks(self, num_src, m):
        if num_src < 1:
            raise ValueError(f"num_src must be at least 1, got {num_src}")
        # MUSIC needs a noise subspace: at least one of the M dimensions left over.
        if self._algorithm != "srp-phat" and num_src >= m:
            raise ValueError(
                f"num_src must be below the number of microphones for {type(self).__name__} "
                f"(its noise subspace has M - num_src dimensions): got num_src={num_src} with M={m}")

    def _used_bins(self, freq_range, freq_bins, freq_hz):
        """The used bins, their span lo..hi and the weights within it (kept between calls
        with the same arguments)."""
        if freq_bins is not None:
            bins = np.asarray(freq_bins, dtype=np.int64)
        elif freq_hz is not None:
            bins = np.array([int(np.round(f / self.fs * self.nfft)) for f in freq_hz], dtype=np.int64)
        else:
            lo, hi = (int(np.round(f / self.fs * self.nfft)) for f in freq_range)
            bins = np.arange(lo, hi, dtype=np.int64)
        bins = np.unique(bins[(bins >= 0) & (bins < self.max_bin)])
        if bins.size == 0:
            raise ValueError("no frequency bin in the requested range")
        lo, hi = int(bins[0]), int(bins[-1]) + 1
        weights = np.isin(np.arange(lo, hi), bins).astype(float)
        weights = [] if weights.all() else weights.tolist()
        return bins, (lo, hi), weights

    def _scale(self, p):
        # soundloc's MUSIC term is ‖a‖²/den = M/den, summed over bins.
        return p / (self.M * self.num_freq)


class MUSIC(_DOA):
    """MUSIC (pyroomacoustics.doa.MUSIC); ``frequency_normalization=True`` is NormMUSIC."""

    def __init__(self, *args, frequency_normalization=False, **kwargs):
        self._normalize = bool(frequency_normalization)
        self.frequency_normalization = self._normalize
        super().__init__(*args, **kwargs)

    def _scale(self, p):
        return p / self.num_freq if self._normalize else super()._scale(p)


class NormMUSIC(MUSIC):
    """MUSIC with per-bin normalisation (pyroomacoustics.doa.NormMUSIC)."""

    def __init__(self, *args, **kwargs):
        kwargs["frequency_normalization"] = True
        super().__init__(*args, **kwargs)


class SRP(_DOA):
    """SRP-PHAT (pyroomacoustics.doa.SRP)."""

    _algorithm = "srp-phat"

    def _scale(self, p):
        # soundloc: Σ_k Re(ãᴴR̃ã)/M²; pyroomacoustics: Σ_k Re(ãᴴR̃ã)/(F·M(M−1)/2).
        pairs = self.M * (self.M - 1) / 2
        return p * self.M ** 2 / (self.num_freq * pairs)


class _Algorithms(dict):
    """pyroomacoustics' ``algorithms`` table; a name it has and soundloc lacks is a clear
    KeyError."""

    def __missing__(self, name):
        raise KeyError(
            f"{name!r}: soundloc.doa provides {', '.join(self)} (pyroomacoustics' CSSM, WAVES, "
            "TOPS and FRIDA are not implemented)")


algorithms = _Algorithms(MUSIC=MUSIC, NormMUSIC=NormMUSIC, SRP=SRP)
