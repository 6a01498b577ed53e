r"""Real spherical harmonics up to order 2: basis, projection, reconstruction and irradiance.

Convention:
    docs/conventions.rst, "Spherical harmonics": real, orthonormal SH up to order 2 (9 coefficients), ordered
    ``(l, m) = (0,0), (1,-1), (1,0), (1,1), (2,-2), (2,-1), (2,0), (2,1), (2,2)`` and stored as
    ``(B, 9, 3)`` (coefficient, RGB). With ``(x, y, z)`` a unit direction in the frame of docs/conventions.rst
    (+X right, +Y up, +Z toward the camera) the basis is

    ========  =======================================
    index     function
    ========  =======================================
    0         ``0.282095``
    1         ``0.488603 y``
    2         ``0.488603 z``
    3         ``0.488603 x``
    4         ``1.092548 x y``
    5         ``1.092548 y z``
    6         ``0.315392 (3 z^2 - 1)``
    7         ``1.092548 x z``
    8         ``0.546274 (x^2 - y^2)``
    ========  =======================================

    with no Condon-Shortley phase (every constant is positive), as in Sloan 2008, "Stupid Spherical
    Harmonics (SH) Tricks", and three.js's ``SphericalHarmonics3``. A light arriving from +Y has a positive
    coefficient 1. Coefficients of lighting are coefficients of *radiance* ``L(d)`` (the value stored in
    the lighting pixel that looks along ``d``).

    Irradiance follows Ramamoorthi & Hanrahan 2001, "An efficient representation for irradiance
    environment maps": ``E_lm = A_l L_lm`` with ``A_0 = pi``, ``A_1 = 2 pi / 3``, ``A_2 = pi / 4``. A white
    Lambertian surface (albedo 1) with normal ``n`` shows ``E(n) / pi`` (docs/conventions.rst, "Units of
    lighting").

Projection by least squares:
    The projection of a lighting image is the integral ``c = integral L(d) Y(d) dOmega``. On a pixel grid
    the obvious quadrature ``c_q = sum_p L_p Y(d_p) omega_p`` (pixel-centre directions ``d_p``, exact solid
    angles ``omega_p``) is not exact even for an order-2 ``L``: the Gram matrix
    ``G = Y^T W Y`` (``W = diag(omega)``) differs from the identity by the quadrature error (measured below).
    :func:`sh_project` therefore solves the weighted normal equations ``G c = Y^T W L``, that is
    ``c = G^{-1} c_q``: a weighted least-squares fit of the order-2 function to the pixels, with the solid
    angles as weights. It reproduces every order-2 function exactly (to rounding) and equals the integral
    projection wherever the quadrature is exact. The ``9 x N`` matrix ``G^{-1} Y^T W`` is precomputed once
    in float64, so projecting is a single matmul.

    Measured in float64 (``tests/sh/test_harmonics.py`` checks these bounds):

    - quadrature error ``max |G - I|``: mirror ball 1.0e-2 at ``S = 32`` and 5.7e-3 at ``S = 64`` (rim
      pixels dominate: there the map compresses directions, so the pixel centre is a poor representative);
      lat-long 1.1e-3 at ``H = 32`` and 2.8e-4 at ``H = 64``;
    - order-2 lighting: plain quadrature is off by up to 1.2e-2 of ``|c|`` (mirror ball 32), 6.6e-3
      (mirror ball 64), 1.8e-3 (lat-long 32); least squares is exact to 2e-14;
    - lighting above order 2, where both are approximations of the integral: for a one-pixel sun on the
      32 x 32 mirror ball the two differ by 0.4% of ``|c|`` (median over pixels; 1.4% at worst), and the
      constant term by 0.27% (0.8% at worst). That is well below the error of placing a sun at its pixel's
      centre (a 32 x 32 pixel spans about 7 degrees). On the ten HDRIs of the shared test data resampled
      to a 32 x 32 mirror ball they differ by at most 1.0% of ``|c|`` and 0.3% in the constant term.

    Consequently the constant coefficient of non-order-2 lighting is not exactly ``0.282095`` times its
    solid-angle-weighted sum; compute energy (docs/conventions.rst, "Relative radiance") from the lighting
    itself.
"""

from __future__ import annotations

import math
from functools import lru_cache

import torch
from torch import nn

from kornia_ilum.core.check import check_choice, check_positive_int, check_same_device, check_tensor
from kornia_ilum.core.compiler import compiler_disable
from kornia_ilum.core.errors import ShapeError, ValueCheckError
from kornia_ilum.geometry.latlong import latlong_directions, latlong_solid_angles
from kornia_ilum.geometry.mirror_ball import mirror_ball_directions, mirror_ball_solid_angles

__all__ = [
    "SH_CONSTANTS",
    "SH_IRRADIANCE_FACTORS",
    "LAYOUTS",
    "sh_basis",
    "sh_project",
    "sh_reconstruct",
    "sh_irradiance",
    "sh_irradiance_at",
    "SHProject",
    "SHReconstruct",
    "SHIrradiance",
    "SHIrradianceAt",
]

#: Normalisation constants of the 9 basis functions, in the order of docs/conventions.rst.
SH_CONSTANTS: tuple[float, ...] = (
    0.5 * math.sqrt(1.0 / math.pi),  # 0.282095
    math.sqrt(3.0 / (4.0 * math.pi)),  # 0.488603
    math.sqrt(3.0 / (4.0 * math.pi)),
    math.sqrt(3.0 / (4.0 * math.pi)),
    0.5 * math.sqrt(15.0 / math.pi),  # 1.092548
    0.5 * math.sqrt(15.0 / math.pi),
    0.25 * math.sqrt(5.0 / math.pi),  # 0.315392
    0.5 * math.sqrt(15.0 / math.pi),
    0.25 * math.sqrt(15.0 / math.pi),  # 0.546274
)

#: Ramamoorthi-Hanrahan factors ``A_l`` per coefficient: pi, 2 pi / 3 (x3), pi / 4 (x5).
SH_IRRADIANCE_FACTORS: tuple[float, ...] = (math.pi,) + (2.0 * math.pi / 3.0,) * 3 + (math.pi / 4.0,) * 5

#: The lighting layouts that projection and reconstruction accept.
LAYOUTS = ("mirror_ball", "latlong")

_HALF = (torch.float16, torch.bfloat16)


def _work_dtype(dtype: torch.dtype) -> torch.dtype:
    """Half-precision inputs are computed in float32 (and cast back by the caller)."""
    return torch.float32 if dtype in _HALF else dtype


def _check_layout(layout: str) -> None:
    check_choice(layout, "layout", LAYOUTS)


def sh_basis(directions: torch.Tensor) -> torch.Tensor:
    r"""Evaluate the 9 real orthonormal SH basis functions (order <= 2) at directions.

    Args:
        directions: ``(..., 3)`` directions ``(x, y, z)`` in the frame of docs/conventions.rst. They are
            normalised first (a zero vector stays zero and gives the value of the basis at ``(0, 0, 0)``).

    Returns:
        ``(..., 9)`` basis values in the order of docs/conventions.rst, dtype of ``directions`` (half
        precision is evaluated in float32 and cast back).

    Shape:
        - Input: :math:`(*, 3)`
        - Output: :math:`(*, 9)`

    Convention:
        docs/conventions.rst, "Spherical harmonics"; the table is in the module docstring. No Condon-Shortley
        phase.

    Examples:
        >>> sh_basis(torch.tensor([0.0, 1.0, 0.0]))[:4]  # from +Y: the (1, -1) function is positive
        tensor([0.2821, 0.4886, 0.0000, 0.0000])
    """
    check_tensor(directions, "directions", ["*", "3"])
    d = directions.to(_work_dtype(directions.dtype))
    d = d / d.norm(dim=-1, keepdim=True).clamp(min=torch.finfo(d.dtype).tiny)
    x, y, z = d.unbind(-1)
    c = SH_CONSTANTS
    basis = torch.stack(
        [
            torch.full_like(x, c[0]),
            c[1] * y,
            c[2] * z,
            c[3] * x,
            c[4] * x * y,
            c[5] * y * z,
            c[6] * (3.0 * z * z - 1.0),
            c[7] * x * z,
            c[8] * (x * x - y * y),
        ],
        dim=-1,
    )
    return basis.to(directions.dtype)


# ----------------------------------------------------------------------------------------------
# fixed matrices of a grid (float64, cached on the CPU)


@compiler_disable  # a cached constant: compiled graphs call it eagerly instead of tracing it
@lru_cache(maxsize=32)
def _grid_f64(layout: str, size: int) -> tuple[torch.Tensor, torch.Tensor]:
    """Basis at the pixel centres ``(N, 9)`` (zero at invalid pixels) and solid angles ``(N,)``."""
    if layout == "mirror_ball":
        d, valid = mirror_ball_directions(size, dtype=torch.float64)
        omega = mirror_ball_solid_angles(size, dtype=torch.float64)
        basis = sh_basis(d) * valid[..., None]
    else:
        d = latlong_directions(size, dtype=torch.float64)
        omega = latlong_solid_angles(size, dtype=torch.float64)
        basis = sh_basis(d)
    return basis.reshape(-1, 9), omega.reshape(-1)


@compiler_disable
@lru_cache(maxsize=32)
def _projection_f64(layout: str, size: int) -> torch.Tensor:
    """The least-squares projection ``(Y^T W Y)^{-1} Y^T W``, ``(9, N)``."""
    basis, omega = _grid_f64(layout, size)
    weighted = basis.T * omega  # Y^T W, (9, N)
    gram = weighted @ basis  # Y^T W Y, (9, 9); the identity for perfect quadrature
    eig = torch.linalg.eigvalsh(gram)
    if float(eig.min()) < 1e-3 * float(eig.max()):
        what = "S" if layout == "mirror_ball" else "H"
        cond = float(eig.max() / eig.min().abs().clamp(min=1e-300))
        raise ValueCheckError(
            f"a {layout} grid of size {what} = {size} is too small to determine 9 SH coefficients "
            f"(Gram matrix condition number {cond:.3g}); use a larger grid"
        )
    return torch.linalg.solve(gram, weighted)


def _lighting_size(lighting: torch.Tensor, layout: str) -> int:
    square = layout == "mirror_ball"
    check_tensor(lighting, "lighting", ["B", "3", "S", "S"] if square else ["B", "3", "H", "2H"])
    h, w = lighting.shape[-2:]
    if w != (h if square else 2 * h):
        want = "(B, 3, S, S)" if square else "(B, 3, H, 2H)"
        raise ShapeError(
            f"lighting must have shape {want} for layout {layout!r}, got {tuple(lighting.shape)}"
        )
    return h


def _project(lighting: torch.Tensor, projection: torch.Tensor) -> torch.Tensor:
    work = _work_dtype(lighting.dtype)
    p = projection.to(device=lighting.device, dtype=work)
    coeffs = lighting.flatten(2).to(work) @ p.T  # (B, 3, 9)
    return coeffs.transpose(1, 2).to(lighting.dtype)


def sh_project(lighting: torch.Tensor, layout: str = "mirror_ball") -> torch.Tensor:
    r"""Project lighting onto the 9 SH coefficients (order <= 2) with exact solid angles.

    A weighted least-squares fit with the pixels' exact solid angles as weights (see the module docstring):
    exact for any order-2 lighting, equal to ``integral L Y dOmega`` up to the grid's quadrature error
    otherwise. Invalid mirror-ball pixels are ignored.

    Args:
        lighting: linear HDR lighting, ``(B, 3, S, S)`` for ``"mirror_ball"`` or ``(B, 3, H, 2H)`` for
            ``"latlong"``. Negative values are allowed (the projection is linear).
        layout: ``"mirror_ball"`` or ``"latlong"``.

    Returns:
        ``(B, 9, 3)`` radiance SH coefficients, dtype of ``lighting`` (half precision is computed in float32
        and cast back).

    Raises:
        ValueCheckError: unknown ``layout``, or a grid too small to determine 9 coefficients (mirror ball
            ``S`` of 1, 2 or 4; lat-long ``H < 3``).
        ShapeError: ``lighting`` has the wrong shape for ``layout``.

    Shape:
        - Input: :math:`(B, 3, S, S)` or :math:`(B, 3, H, 2H)`
        - Output: :math:`(B, 9, 3)`

    Convention:
        docs/conventions.rst: frame, mirror-ball and lat-long pixel centres, SH order. Pixel-centre directions
        and :func:`~kornia_ilum.geometry.mirror_ball_solid_angles` /
        :func:`~kornia_ilum.geometry.latlong_solid_angles`.

    Examples:
        >>> sh = sh_project(torch.ones(1, 3, 32, 32))  # uniform radiance 1
        >>> sh[0, 0]  # the constant term: sqrt(4 pi)
        tensor([3.5449, 3.5449, 3.5449])
        >>> bool(sh[0, 1:].abs().max() < 1e-5)  # and nothing else
        True
    """
    _check_layout(layout)
    size = _lighting_size(lighting, layout)
    return _project(lighting, _projection_f64(layout, size))


def _reconstruct(
    sh: torch.Tensor, basis: torch.Tensor, *, height: int, width: int, clamp_negative: bool
) -> torch.Tensor:
    work = _work_dtype(sh.dtype)
    b = basis.to(device=sh.device, dtype=work)
    img = sh.to(work).transpose(1, 2) @ b.T  # (B, 3, N)
    if clamp_negative:
        img = img.clamp(min=0.0)
    return img.reshape(sh.shape[0], 3, height, width).to(sh.dtype)


def _grid_shape(layout: str, size: int) -> tuple[int, int]:
    return (size, size) if layout == "mirror_ball" else (size, 2 * size)


def sh_reconstruct(
    sh: torch.Tensor, size: int = 32, layout: str = "mirror_ball", clamp_negative: bool = False
) -> torch.Tensor:
    r"""Evaluate SH lighting at the pixel centres of a mirror ball or lat-long map.

    Reconstruction is exact: the order-2 function is evaluated as is, so it may be negative near the
    antipode of a bright light (ringing). ``clamp_negative=True`` clips it at 0 to obtain valid lighting
    (docs/conventions.rst: lighting is never negative); the clipped image is then no longer an order-2
    function and :func:`sh_project` of it does not return ``sh``.

    Args:
        sh: ``(B, 9, 3)`` radiance SH coefficients.
        size: ``S`` of the ``S x S`` mirror ball, or ``H`` of the ``H x 2H`` lat-long map.
        layout: ``"mirror_ball"`` or ``"latlong"``.
        clamp_negative: clip negative radiance to 0.

    Returns:
        ``(B, 3, S, S)`` or ``(B, 3, H, 2H)`` radiance, dtype of ``sh``; invalid mirror-ball pixels hold 0.

    Shape:
        - Input: :math:`(B, 9, 3)`
        - Output: :math:`(B, 3, S, S)` or :math:`(B, 3, H, 2H)`

    Convention:
        docs/conventions.rst: pixel-centre directions of each layout, SH order and frame.

    Notes:
        The irradiance map (irradiance for every normal direction) is
        ``sh_reconstruct(sh_irradiance(sh), ...)``.

    Examples:
        >>> sh = torch.zeros(1, 9, 3)
        >>> sh[:, 0] = 2 * math.sqrt(math.pi)  # uniform radiance 1
        >>> img = sh_reconstruct(sh, size=4)
        >>> img[0, 0].round(decimals=4)  # invalid corners hold 0
        tensor([[0., 1., 1., 0.],
                [1., 1., 1., 1.],
                [1., 1., 1., 1.],
                [0., 1., 1., 0.]])
    """
    _check_layout(layout)
    check_tensor(sh, "sh", ["B", "9", "3"])
    check_positive_int(size, "size")
    basis, _ = _grid_f64(layout, size)
    height, width = _grid_shape(layout, size)
    return _reconstruct(sh, basis, height=height, width=width, clamp_negative=clamp_negative)


def sh_irradiance(sh: torch.Tensor) -> torch.Tensor:
    r"""SH coefficients of irradiance from those of radiance (Ramamoorthi & Hanrahan 2001).

    ``E_lm = A_l L_lm`` with ``A_0 = pi``, ``A_1 = 2 pi / 3``, ``A_2 = pi / 4``: the exact SH coefficients
    of ``E(n) = integral L(d) max(0, n . d) dOmega`` for bands 0 to 2. Bands above 2 of ``E`` are dropped:
    for a single directional light of normal irradiance ``E_0`` the order-2 irradiance is off by at most
    ``0.094 E_0`` (at 90 degrees from the light) and ``0.031 E_0`` on average over normals; smooth lighting
    fares much better.

    Args:
        sh: ``(B, 9, 3)`` radiance SH coefficients.

    Returns:
        ``(B, 9, 3)`` irradiance SH coefficients.

    Raises:
        ShapeError: ``sh`` is not ``(B, 9, 3)``.

    Shape:
        - Input: :math:`(B, 9, 3)`
        - Output: :math:`(B, 9, 3)`

    Convention:
        docs/conventions.rst, "Spherical harmonics". Irradiance in the lighting's units times steradians; a
        white Lambertian surface shows ``E / pi``.

    Examples:
        >>> sh = torch.zeros(1, 9, 3)
        >>> sh[:, 0] = 2 * math.sqrt(math.pi)  # uniform radiance 1
        >>> sh_irradiance(sh)[0, 0] / (2 * math.sqrt(math.pi))  # pi
        tensor([3.1416, 3.1416, 3.1416])
    """
    check_tensor(sh, "sh", ["B", "9", "3"])
    a = torch.tensor(SH_IRRADIANCE_FACTORS, device=sh.device, dtype=sh.dtype)
    return sh * a[:, None]


def sh_irradiance_at(sh: torch.Tensor, normals: torch.Tensor) -> torch.Tensor:
    r"""Irradiance ``E(n)`` of SH lighting at surface normals.

    ``E(n) = sum_lm A_l L_lm Y_lm(n)`` (Ramamoorthi & Hanrahan 2001, eq. 7), the order-2 approximation of
    ``integral L(d) max(0, n . d) dOmega``.

    Args:
        sh: ``(B, 9, 3)`` radiance SH coefficients.
        normals: ``(B, N, 3)`` (or ``(1, N, 3)``, shared by the batch) normals in the frame of
            docs/conventions.rst; they are normalised first.

    Returns:
        ``(B, N, 3)`` RGB irradiance, dtype of ``sh``. It can be slightly negative facing away from a
        strong light (order-2 ringing).

    Raises:
        ShapeError: the batch sizes differ (and ``normals``' is not 1).

    Shape:
        - Input: :math:`(B, 9, 3)` and :math:`(B, N, 3)`
        - Output: :math:`(B, N, 3)`

    Convention:
        docs/conventions.rst, "Frames" and "Spherical harmonics".

    Examples:
        >>> sh = torch.zeros(1, 9, 3)
        >>> sh[:, 0] = 2 * math.sqrt(math.pi)  # uniform radiance 1: E = pi everywhere
        >>> sh_irradiance_at(sh, torch.tensor([[[0.0, 0.0, 1.0], [1.0, 0.0, 0.0]]]))
        tensor([[[3.1416, 3.1416, 3.1416],
                 [3.1416, 3.1416, 3.1416]]])
    """
    check_tensor(sh, "sh", ["B", "9", "3"])
    check_tensor(normals, "normals", ["B", "N", "3"])
    check_same_device(("sh", sh), ("normals", normals))
    if normals.shape[0] not in (1, sh.shape[0]):
        raise ShapeError(
            f"normals must have batch size 1 or {sh.shape[0]} (that of sh), got shape {tuple(normals.shape)}"
        )
    work = _work_dtype(sh.dtype)
    basis = sh_basis(normals.to(work))  # (B, N, 9)
    return (basis @ sh_irradiance(sh.to(work))).to(sh.dtype)


# ----------------------------------------------------------------------------------------------
# module twins


def _factory(device: torch.device | str | None, dtype: torch.dtype | None) -> dict:
    return {"device": device, "dtype": dtype if dtype is not None else torch.get_default_dtype()}


class SHProject(nn.Module):
    r"""Module twin of :func:`sh_project` for a fixed grid.

    The ``(9, N)`` least-squares projection matrix is a non-persistent buffer, so that the forward pass is a
    single matmul.

    Args:
        size: ``S`` of the mirror ball, or ``H`` of the lat-long map.
        layout: ``"mirror_ball"`` or ``"latlong"``.
        device: device of the buffer.
        dtype: dtype of the buffer (default: :func:`torch.get_default_dtype`); pass ``torch.float64`` for
            float64 inputs, as ``.double()`` of a float32 buffer keeps its float32 rounding.

    Shape:
        - Input: :math:`(B, 3, S, S)` or :math:`(B, 3, H, 2H)`, of the module's ``size``
        - Output: :math:`(B, 9, 3)`

    Examples:
        >>> proj = SHProject(32)
        >>> proj(torch.ones(2, 3, 32, 32)).shape
        torch.Size([2, 9, 3])
    """

    def __init__(
        self,
        size: int = 32,
        layout: str = "mirror_ball",
        *,
        device: torch.device | str | None = None,
        dtype: torch.dtype | None = None,
    ) -> None:
        super().__init__()
        _check_layout(layout)
        check_positive_int(size, "size")
        self.size = size
        self.layout = layout
        self.register_buffer(
            "projection",
            _projection_f64(layout, size).to(**_factory(device, dtype), copy=True),
            persistent=False,
        )

    def forward(self, lighting: torch.Tensor) -> torch.Tensor:
        got = _lighting_size(lighting, self.layout)
        if got != self.size:
            raise ShapeError(
                f"lighting must have size {self.size} for this SHProject, got shape {tuple(lighting.shape)}"
            )
        return _project(lighting, self.projection)

    def extra_repr(self) -> str:
        return f"size={self.size}, layout={self.layout!r}"


class SHReconstruct(nn.Module):
    r"""Module twin of :func:`sh_reconstruct`; the basis at the pixel centres is a non-persistent buffer.

    Args:
        size: ``S`` of the mirror ball, or ``H`` of the lat-long map.
        layout: ``"mirror_ball"`` or ``"latlong"``.
        clamp_negative: clip negative radiance to 0.
        device: device of the buffer.
        dtype: dtype of the buffer (default: :func:`torch.get_default_dtype`).

    Shape:
        - Input: :math:`(B, 9, 3)`
        - Output: :math:`(B, 3, S, S)` or :math:`(B, 3, H, 2H)`

    Examples:
        >>> SHReconstruct(16, layout="latlong")(torch.zeros(2, 9, 3)).shape
        torch.Size([2, 3, 16, 32])
    """

    def __init__(
        self,
        size: int = 32,
        *,
        layout: str = "mirror_ball",
        clamp_negative: bool = False,
        device: torch.device | str | None = None,
        dtype: torch.dtype | None = None,
    ) -> None:
        super().__init__()
        _check_layout(layout)
        check_positive_int(size, "size")
        self.size = size
        self.layout = layout
        self.clamp_negative = clamp_negative
        basis, _ = _grid_f64(layout, size)
        self.register_buffer("basis", basis.to(**_factory(device, dtype), copy=True), persistent=False)

    def forward(self, sh: torch.Tensor) -> torch.Tensor:
        check_tensor(sh, "sh", ["B", "9", "3"])
        height, width = _grid_shape(self.layout, self.size)
        return _reconstruct(sh, self.basis, height=height, width=width, clamp_negative=self.clamp_negative)

    def extra_repr(self) -> str:
        return f"size={self.size}, layout={self.layout!r}, clamp_negative={self.clamp_negative}"


class SHIrradiance(nn.Module):
    r"""Module twin of :func:`sh_irradiance`.

    Shape:
        - Input: :math:`(B, 9, 3)`
        - Output: :math:`(B, 9, 3)`

    Examples:
        >>> SHIrradiance()(torch.zeros(1, 9, 3)).shape
        torch.Size([1, 9, 3])
    """

    def forward(self, sh: torch.Tensor) -> torch.Tensor:
        return sh_irradiance(sh)


class SHIrradianceAt(nn.Module):
    r"""Module twin of :func:`sh_irradiance_at`.

    Shape:
        - Input: :math:`(B, 9, 3)` and :math:`(B, N, 3)` (or :math:`(1, N, 3)`)
        - Output: :math:`(B, N, 3)`

    Examples:
        >>> SHIrradianceAt()(torch.zeros(2, 9, 3), torch.ones(2, 5, 3)).shape
        torch.Size([2, 5, 3])
    """

    def forward(self, sh: torch.Tensor, normals: torch.Tensor) -> torch.Tensor:
        return sh_irradiance_at(sh, normals)
