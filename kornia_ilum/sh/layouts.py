r"""Converters between our SH lighting and the SH layouts of DPR, SfSNet, DECA, ARCore and WebXR.

Every converter is linear (a fixed signed permutation, for DPR a rotation, and a scale per coefficient), so
round trips are exact to rounding (bit-exact for ARCore / WebXR, whose conversion is only signs) and
gradients pass through.

Convention:
    Ours (kornia_ilum's, docs/conventions.rst, "Spherical harmonics"): ``(B, 9, 3)`` radiance coefficients
    ``L_lm`` in the orthonormal real basis of :mod:`kornia_ilum.sh.harmonics` (that order, no
    Condon-Shortley phase, frame +X right, +Y up, +Z toward the camera; a direction means "light arriving
    from it"). A white Lambertian surface with normal ``n`` shows ``E(n) / pi`` where
    ``E = sum_lm A_l L_lm Y_lm(n)`` and ``A = (pi, 2 pi / 3, pi / 4)``
    (:func:`~kornia_ilum.sh.sh_irradiance_at`). Every converter here is defined so that the other project's
    own shading formula of the converted coefficients gives exactly that ``E(n) / pi``
    (docs/conventions.rst, "Units of lighting": the same pixels for the same albedo), which fixes the
    factors in the last column.

    The conventions, as read from each project's own code (sources in each function). "Axes" gives their
    ``x, y, z`` in our ``X, Y, Z``; "shading" is what their renderer multiplies the albedo with, as a
    function of their coefficients ``c`` read as radiance; the last column is the converter.

    ======  ===============  =================  =================  ===========  ======================
    layout  shape            basis order        axes (up;          shading      our ``L`` from
                             (own axes)         toward camera)                  their ``c``
    ======  ===============  =================  =================  ===========  ======================
    ours    ``(B, 9, 3)``    1 y z x xy yz      X Y Z              ``E/pi``     ``L = c``
                             3z2-1 xz x2-y2     (+y; +z)
    DPR     ``(B, 9)`` grey  as ours (shtools,  X -Z Y             ``E``        ``pi R^T c``, ``R``
                             no CS phase)       (+z; -y)                        the axes' rotation
    SfSNet  ``(B, 27)``      1 z x y 3z2-1      -Y X Z             ``E``        ``pi`` times a signed
            R, then G, B     xz yz x2-y2 xy     (-x; +z)                        permutation
    DECA    ``(B, 9, 3)``    1 x y z xy xz      X Y Z              ``E``, but   ``c0``, ``pi c1..c8``,
                             yz x2-y2 3z2-1     (+y; +z)           ``A_0 = 1``  reordered
    ARCore  ``(B, 27)`` RGB  as ours, with the  X Y Z (world,      ``E/pi``     signs ``(-1)^m``
            per coefficient  phase ``(-1)^m``   camera at origin)
    WebXR   = ARCore         = ARCore           probe space        ``E/pi``     = ARCore
    ======  ===============  =================  =================  ===========  ======================

    What the numbers mean:

    - DPR and SfSNet coefficients are radiance coefficients in the orthonormal basis (DPR projects HDR
      environment maps with shtools, ``norm=4``), and their renderers multiply the albedo by the irradiance
      ``E`` itself, not ``E / pi``; to keep the same pixels, our coefficients are ``pi`` times theirs.
      Divide :func:`sh_from_dpr` / :func:`sh_from_sfsnet` by ``pi`` for the other reading (the same
      environment-map radiance, a ``pi`` times darker render in the units of docs/conventions.rst).
    - DECA's band 0 lacks ``A_0 = pi``; the code that reproduces its shading has ``c[0] = L_00`` and
      ``c[i] = L_lm / pi`` for the rest.
    - DPR, SfSNet and DECA all fit sRGB-encoded (not linearised) photographs, DPR the ``L`` of CIE Lab, so
      their absolute scale is only "sRGB-ish"; nothing here linearises. ARCore's units are relative.
"""

from __future__ import annotations

import math

import torch

from kornia_ilum.core.check import check_choice, check_tensor

__all__ = [
    "DPR_CHANNELS",
    "sh_to_dpr",
    "sh_from_dpr",
    "sh_to_sfsnet",
    "sh_from_sfsnet",
    "sh_to_deca",
    "sh_from_deca",
    "sh_to_arcore",
    "sh_from_arcore",
    "sh_to_webxr",
    "sh_from_webxr",
]

# DECA: deca[i] = spec[_DECA_FROM_SPEC[i]] * _DECA_SCALE[i]
_DECA_FROM_SPEC = (0, 3, 1, 2, 4, 7, 5, 8, 6)
_SPEC_FROM_DECA = (0, 2, 3, 1, 4, 6, 8, 5, 7)
_DECA_SCALE = (1.0,) + (1.0 / math.pi,) * 8

# ARCore / WebXR: Condon-Shortley phase (-1)^m on the m = -1, +1 functions (l = 1 and 2)
_ARCORE_SIGN = (1.0, -1.0, 1.0, -1.0, 1.0, -1.0, 1.0, -1.0, 1.0)


_S3 = math.sqrt(3.0) / 2.0

# DPR: its basis function k, evaluated in its own axes (x, y, z) = (X, -Z, Y), is sum_j R[k][j] Y_j (ours);
# e.g. its y = -Z, and its 3 z^2 - 1 = 3 Y^2 - 1 = -(3 Z^2 - 1) / 2 - 3 (X^2 - Y^2) / 2.
_DPR_ROTATION = (
    (1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
    (0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0),  # y = -Z
    (0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0),  # z = Y
    (0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0),  # x = X
    (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0),  # x y = -X Z
    (0.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0),  # y z = -Z Y
    (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, -0.5, 0.0, -_S3),  # 3 z^2 - 1 = 3 Y^2 - 1
    (0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0),  # x z = X Y
    (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, -_S3, 0.0, 0.5),  # x^2 - y^2 = X^2 - Z^2
)

# SfSNet: its basis function k in its axes (x, y, z) = (-Y, X, Z) is
# _SFSNET_SIGN[k] * Y_{_SFSNET_FROM_SPEC[k]} (our basis).
_SFSNET_FROM_SPEC = (0, 2, 1, 3, 6, 5, 7, 8, 4)  # 1, z, x, y, 3z^2-1, xz, yz, x^2-y^2, xy
_SFSNET_SIGN = (1.0, 1.0, -1.0, 1.0, 1.0, -1.0, 1.0, -1.0, -1.0)
_SPEC_FROM_SFSNET = tuple(_SFSNET_FROM_SPEC.index(j) for j in range(9))

#: Channel choices of :func:`sh_to_dpr`, with the RGB weights of each (luminance: Rec. 709 / sRGB primaries).
DPR_CHANNELS: dict[str, tuple[float, float, float]] = {
    "luminance": (0.2126, 0.7152, 0.0722),
    "r": (1.0, 0.0, 0.0),
    "g": (0.0, 1.0, 0.0),
    "b": (0.0, 0.0, 1.0),
}


def _const(values: tuple[float, ...], like: torch.Tensor) -> torch.Tensor:
    return torch.tensor(values, device=like.device, dtype=like.dtype)[:, None]


def _work(x: torch.Tensor) -> torch.Tensor:
    """Half-precision inputs are computed in float32 (and cast back by the caller)."""
    return x.float() if x.dtype in (torch.float16, torch.bfloat16) else x


def _index(values: tuple[int, ...], like: torch.Tensor) -> torch.Tensor:
    return torch.tensor(values, device=like.device, dtype=torch.long)


def sh_to_deca(sh: torch.Tensor) -> torch.Tensor:
    r"""Convert our SH lighting to DECA's ``light`` code.

    DECA (Feng et al. 2021, "Learning an Animatable Detailed 3D Face Model from In-The-Wild Images")
    shades a face as ``albedo * shading`` with
    ``shading(N) = sum_i light[i] * f_i * p_i(N)``, ``p = (1, x, y, z, xy, xz, yz, x^2 - y^2, 3 z^2 - 1)``
    and ``f = (1/sqrt(4 pi), A_1 sqrt(3/(4 pi)) [x3], A_2 * 3 sqrt(5/(12 pi)) [x3],
    A_2 * 3/2 sqrt(5/(12 pi)), A_2 * 1/2 sqrt(5/(4 pi)))``: the orthonormal constants times the
    Ramamoorthi-Hanrahan factors, except that band 0 lacks ``A_0 = pi``.

    This function returns the code for which DECA's ``shading`` equals ``E(n) / pi``, the value a white
    Lambertian surface shows under ``sh`` (docs/conventions.rst, "Units of lighting"): ``light[0] = L_00`` and
    ``light[i] = L_lm / pi`` for the other coefficients, reordered to DECA's basis order.

    Args:
        sh: ``(B, 9, 3)`` our SH lighting.

    Returns:
        ``(B, 9, 3)`` DECA ``codedict['light']``.

    Raises:
        ShapeError: ``sh`` is not ``(B, 9, 3)``.

    Shape:
        - Input: :math:`(B, 9, 3)`
        - Output: :math:`(B, 9, 3)`

    Convention:
        Source: ``decalib/utils/renderer.py`` of https://github.com/yfeng95/DECA (``SRenderY.__init__``,
        ``constant_factor``; ``SRenderY.add_SHlight``). The normals DECA shades with are FLAME-space vertex
        normals (``decalib/deca.py``, ``decode``: ``self.render(verts, trans_verts, albedo, light)``), and
        FLAME space under DECA's orthographic camera is our frame: ``batch_orth_proj`` only scales and
        shifts x, y; the renderer then flips y and z for rasterisation, and its visibility mask keeps
        normals whose flipped z is negative, i.e. outward normals facing +Z. No sign changes are needed.

        Uncertain: the absolute scale. DECA fits sRGB-encoded photographs without linearising them, so its
        light codes are in "sRGB-ish" units; and another reading of its code (``light`` as plain radiance
        coefficients, the missing ``pi`` in band 0 a slip) would drop the ``1 / pi`` on bands 1 and 2. The
        definition here reproduces DECA's shading exactly; the tests check it against DECA's formula.

    Examples:
        >>> sh = torch.zeros(1, 9, 3)
        >>> sh[:, 1] = 1.0  # light from +Y (our coefficient (1, -1))
        >>> sh_to_deca(sh)[0, :, 0]  # lands on DECA's y coefficient, divided by pi
        tensor([0.0000, 0.0000, 0.3183, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000])
    """
    check_tensor(sh, "sh", ["B", "9", "3"])
    return sh.index_select(1, _index(_DECA_FROM_SPEC, sh)) * _const(_DECA_SCALE, sh)


def sh_from_deca(light: torch.Tensor) -> torch.Tensor:
    r"""Convert DECA's ``light`` code to our SH lighting; the inverse of :func:`sh_to_deca`.

    Args:
        light: ``(B, 9, 3)`` DECA ``codedict['light']``.

    Returns:
        ``(B, 9, 3)`` our SH lighting (see :func:`sh_to_deca` for the convention and its source).

    Raises:
        ShapeError: ``light`` is not ``(B, 9, 3)``.

    Shape:
        - Input: :math:`(B, 9, 3)`
        - Output: :math:`(B, 9, 3)`

    Convention:
        docs/conventions.rst, "Spherical harmonics" (our order and frame) and "Units of lighting"; the other
        layout as in :func:`sh_to_deca`.

    Examples:
        >>> light = torch.zeros(1, 9, 3)
        >>> light[:, 0] = 1.0
        >>> sh_from_deca(light)[0, 0]
        tensor([1., 1., 1.])
    """
    check_tensor(light, "light", ["B", "9", "3"])
    return (light / _const(_DECA_SCALE, light)).index_select(1, _index(_SPEC_FROM_DECA, light))


def sh_to_arcore(sh: torch.Tensor) -> torch.Tensor:
    r"""Convert our SH lighting to ARCore's 27 floats (also WebXR's, see :func:`sh_to_webxr`).

    ARCore's ``LightEstimate.getEnvironmentalHdrAmbientSphericalHarmonics()`` (C:
    ``ArLightEstimate_getEnvironmentalHdrAmbientSphericalHarmonics``, ``out_coefficients_27``) returns 9
    coefficients x RGB, interleaved per coefficient (``[c0.r, c0.g, c0.b, c1.r, ...]``), in our
    ``(l, m)`` order. They are *radiance* coefficients in the orthonormal basis, but with the
    Condon-Shortley phase of Filament's SH (Filament's ``CubemapSH``), so the ``m = +-1`` functions of
    bands 1 and 2 (indices 1, 3, 5, 7) change sign: ``c_arcore = s * c_spec``,
    ``s = (+, -, +, -, +, -, +, -, +)``. A light from +Y gives a *negative* ``c_arcore[1]``.

    Args:
        sh: ``(B, 9, 3)`` our SH lighting.

    Returns:
        ``(B, 27)`` ARCore coefficients.

    Raises:
        ShapeError: ``sh`` is not ``(B, 9, 3)``.

    Shape:
        - Input: :math:`(B, 9, 3)`
        - Output: :math:`(B, 27)`

    Convention:
        Source: the ARCore SDK sample ``samples/hello_ar_java`` of
        https://github.com/google-ar/arcore-android-sdk: ``sphericalHarmonicFactors`` =
        ``(0.282095, -0.325735, 0.325735, -0.325735, 0.273137, -0.273137, 0.078848, -0.273137, 0.136569)``
        (our constants times ``A_l / pi`` times the sign ``s``) multiply the ARCore coefficients, and
        ``shaders/environmental_hdr.frag`` evaluates them with the sign-free polynomials
        ``1, y, z, x, yx, yz, 3z^2 - 1, zx, x^2 - y^2`` of the world-space normal to get the Lambertian
        ``E(n) / pi``. The tests check that formula against :func:`~kornia_ilum.sh.sh_irradiance_at`.
        Babylon.js reads WebXR's array the same way (``Maths/sphericalPolynomial.ts``,
        ``updateFromHarmonics`` negates ``l1_1``, ``l11``, ``l2_1``, ``l21``).

        Frame: ARCore world space (right-handed, +Y up against gravity; cameras look along their -Z). It
        coincides with our frame when the camera's rotation in the world is the identity; otherwise
        rotate the lighting into the camera frame first (not done here).

        Uncertain: the absolute scale (ARCore's relative linear units are not calibrated to the camera's
        pixel values; no factor is applied), and three.js's ``XREstimatedLight``, which copies WebXR's
        array into its sign-free ``SphericalHarmonics3`` (that reading would flip coefficients 1, 3, 5, 7).

    Examples:
        >>> sh = torch.zeros(1, 9, 3)
        >>> sh[:, 1] = 1.0  # light from +Y
        >>> sh_to_arcore(sh)[0, :6]
        tensor([ 0.,  0.,  0., -1., -1., -1.])
    """
    check_tensor(sh, "sh", ["B", "9", "3"])
    return (sh * _const(_ARCORE_SIGN, sh)).reshape(sh.shape[0], 27)


def sh_from_arcore(coefficients: torch.Tensor) -> torch.Tensor:
    r"""Convert ARCore's (or WebXR's) 27 floats to our SH lighting; the inverse of :func:`sh_to_arcore`.

    Args:
        coefficients: ``(B, 27)`` coefficients, RGB interleaved per coefficient.

    Returns:
        ``(B, 9, 3)`` our SH lighting (see :func:`sh_to_arcore` for the convention and its sources).

    Raises:
        ShapeError: ``coefficients`` is not ``(B, 27)``.

    Shape:
        - Input: :math:`(B, 27)`
        - Output: :math:`(B, 9, 3)`

    Convention:
        docs/conventions.rst, "Spherical harmonics" (our order and frame) and "Units of lighting"; the other
        layout as in :func:`sh_to_arcore`.

    Examples:
        >>> sh_from_arcore(torch.arange(27.0)[None])[0, 1]  # coefficient 1 changes sign
        tensor([-3., -4., -5.])
    """
    check_tensor(coefficients, "coefficients", ["B", "27"])
    sh = coefficients.reshape(coefficients.shape[0], 9, 3)
    return sh * _const(_ARCORE_SIGN, sh)


#: WebXR's ``XRLightEstimate.sphericalHarmonicsCoefficients`` is ARCore's array, copied verbatim.
#:
#: The WebXR Lighting Estimation spec (https://immersive-web.github.io/lighting-estimation/) fixes only the
#: layout: a ``Float32Array`` of 27, every 3 elements the RGB of one coefficient, in the order
#: ``C00, C1-1, C10, C11, C2-2, C2-1, C20, C21, C22``, relative to the light probe's ``probeSpace`` (WebXR
#: spaces: +Y up, -Z forward). It states no normalisation or phase. Its only implementation, Chromium on
#: ARCore, copies ARCore's 27 floats unchanged (``device/vr/android/arcore/arcore_impl.cc``,
#: ``GetLightProbe``), so the ARCore convention applies; see :func:`sh_to_arcore` for what is uncertain.
sh_to_webxr = sh_to_arcore

#: Inverse of :data:`sh_to_webxr`; an alias of :func:`sh_from_arcore` (see :data:`sh_to_webxr`).
sh_from_webxr = sh_from_arcore


def _matrix(values: tuple[tuple[float, ...], ...], like: torch.Tensor) -> torch.Tensor:
    return torch.tensor(values, device=like.device, dtype=like.dtype)


def sh_to_dpr(sh: torch.Tensor, channel: str = "luminance") -> torch.Tensor:
    r"""Convert our SH lighting to DPR's 9 grey SH coefficients.

    DPR (Zhou et al. 2019, "Deep Single-Image Portrait Relighting") relights the ``L`` channel of CIE Lab
    with one grey SH lighting of 9 coefficients. Its renderer (``utils/utils_SH.py``, ``SH_basis`` and
    ``get_shading``) shades ``shading(n) = sum_k c_k A_l Y_k(n')``: the orthonormal basis in our order
    and signs (``1, y, z, x, yx, yz, 3z^2 - 1, xz, x^2 - y^2``, shtools' real SH without Condon-Shortley
    phase) times ``att = pi (1, 2/3, 1/4)``, evaluated at the normal ``n'`` in DPR's axes. ``c`` are
    radiance coefficients (DPR's lightings are shtools projections of environment maps) and ``shading`` is
    their irradiance ``E``, not ``E / pi``.

    DPR's axes are shtools' (``utils/utils_normal.py``, ``sh_cvt``; the half sphere of
    ``testNetwork_demo_512.py``): x right, **z up**, **y away from the camera** (the visible half sphere has
    ``y = -sqrt(1 - x^2 - z^2)``). So ``n' = (X, -Z, Y)`` for our normal ``(X, Y, Z)``, and in our
    basis DPR's function ``k`` is ``sum_j R_kj Y_j`` with ``R`` a rotation that keeps bands (signed
    permutation except for ``3z^2 - 1`` and ``x^2 - y^2``, which mix). This function returns
    ``c = R L_grey / pi``, for which DPR's shading is exactly ``E(n) / pi`` of the grey lighting: the value
    that a white Lambertian surface shows under ``sh`` (docs/conventions.rst, "Units of lighting").

    Args:
        sh: ``(B, 9, 3)`` our SH lighting.
        channel: which grey lighting DPR gets: ``"luminance"`` (default; ``0.2126 R + 0.7152 G + 0.0722 B``,
            the linear luminance of Rec. 709 / sRGB primaries), or one of ``"r"``, ``"g"``, ``"b"``. The
            conversion is linear, so DPR's shading of the result is that channel (or the luminance) of
            our shading. See :data:`DPR_CHANNELS`.

    Returns:
        ``(B, 9)`` DPR coefficients (DPR's network takes them as ``(B, 9, 1, 1)``: ``reshape(B, 9, 1, 1)``).

    Raises:
        ShapeError: ``sh`` is not ``(B, 9, 3)``.
        ValueCheckError: ``channel`` is not one of :data:`DPR_CHANNELS`.

    Shape:
        - Input: :math:`(B, 9, 3)`
        - Output: :math:`(B, 9)`

    Convention:
        Source: https://github.com/zhhoper/DPR, ``utils/utils_SH.py`` (basis, constants, ``att``),
        ``utils/utils_shtools.py`` (shtools order of the 9 coefficients), ``utils/utils_normal.py`` (axes),
        ``testNetwork_demo_512.py`` (the rendered half sphere). Round trip: ``sh_from_dpr(sh_to_dpr(sh))``
        is the grey lighting of ``sh`` in every channel.

        Uncertain: the absolute scale. DPR works on the Lab ``L`` of sRGB photographs divided by 255, which
        is not linear in radiance; and its demo scales the shipped lightings by 0.7. No factor is applied
        for either.

    Examples:
        >>> sh = torch.zeros(1, 9, 3)
        >>> sh[:, 1] = 1.0  # light from +Y: DPR's z coefficient (index 2), divided by pi
        >>> sh_to_dpr(sh, "g")[0]
        tensor([0.0000, 0.0000, 0.3183, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000])
    """
    check_tensor(sh, "sh", ["B", "9", "3"])
    check_choice(channel, "channel", tuple(DPR_CHANNELS))
    work = _work(sh)
    grey = work @ torch.tensor(DPR_CHANNELS[channel], device=sh.device, dtype=work.dtype)  # (B, 9)
    out = grey @ (_matrix(_DPR_ROTATION, work).T / math.pi)
    return out.to(sh.dtype)


def sh_from_dpr(coefficients: torch.Tensor) -> torch.Tensor:
    r"""Convert DPR's 9 grey SH coefficients to our (grey) SH lighting; the inverse of :func:`sh_to_dpr`.

    Returns ``L = pi R^T c`` in all three channels, so that a white Lambertian surface under our
    lighting shows DPR's shading of ``c`` (see :func:`sh_to_dpr` for the convention and its sources).
    Divide by ``pi`` to read ``c`` as the radiance of an environment map instead.

    Args:
        coefficients: ``(B, 9)`` DPR coefficients (flatten DPR's ``(B, 9, 1, 1)`` first).

    Returns:
        ``(B, 9, 3)`` our SH lighting, the same in R, G and B.

    Raises:
        ShapeError: ``coefficients`` is not ``(B, 9)``.

    Shape:
        - Input: :math:`(B, 9)`
        - Output: :math:`(B, 9, 3)`

    Convention:
        docs/conventions.rst, "Spherical harmonics" (our order and frame) and "Units of lighting"; the other
        layout as in :func:`sh_to_dpr`.

    Examples:
        >>> c = torch.zeros(1, 9)
        >>> c[:, 1] = 1.0  # DPR's y: light from behind the subject (our -Z)
        >>> (sh_from_dpr(c)[0, :, 0] / math.pi).round(decimals=4) + 0.0
        tensor([ 0.,  0., -1.,  0.,  0.,  0.,  0.,  0.,  0.])
    """
    check_tensor(coefficients, "coefficients", ["B", "9"])
    work = _work(coefficients)
    spec = work @ (_matrix(_DPR_ROTATION, work) * math.pi)  # (B, 9): pi R^T c, as row vectors
    return spec[:, :, None].expand(-1, -1, 3).to(coefficients.dtype).contiguous()


def sh_to_sfsnet(sh: torch.Tensor) -> torch.Tensor:
    r"""Convert our SH lighting to SfSNet's 27 lighting values.

    SfSNet (Sengupta et al. 2018, "SfSNet: Learning Shape, Reflectance and Illuminance of Faces in the
    Wild") predicts ``fc_light``, 27 values: 9 for R, then 9 for G, then 9 for B. Its shading layer
    (``SfSNet_train/python/Shading_Layer.py``, ``functions/normal_harmonics.m``) computes
    ``shading = sum_k c_k H_k(n')`` with ``H = att * (1/sqrt(4 pi), sqrt(3/(4 pi)) (z, x, y),
    1/2 sqrt(5/(4 pi)) (2z^2 - x^2 - y^2), 3 sqrt(5/(12 pi)) (xz, yz), 3 sqrt(5/(48 pi)) (x^2 - y^2),
    3 sqrt(5/(12 pi)) xy)`` and ``att = pi (1, 2/3, 1/4)`` (``c1 .. c5`` of the Python port): the orthonormal
    basis in its own order times the Ramamoorthi-Hanrahan factors, i.e. the irradiance ``E`` of radiance
    coefficients ``c`` (not ``E / pi``). The reconstruction is ``albedo * shading``.

    SfSNet's normal axes are **x down**, y right, z toward the camera: ``n' = (-Y, X, Z)`` for our normal
    ``(X, Y, Z)``. Then every SfSNet function is one of ours up to sign (``x = -Y``, ``xz = -YZ``,
    ``x^2 - y^2 = -(X^2 - Y^2)``, ``xy = -XY``), and this function returns the signed permutation of
    ``L / pi``, for which SfSNet's shading is exactly ``E(n) / pi``, what a white Lambertian surface shows
    under ``sh`` (docs/conventions.rst, "Units of lighting").

    Args:
        sh: ``(B, 9, 3)`` our SH lighting.

    Returns:
        ``(B, 27)`` SfSNet ``fc_light``: ``[R c_0..c_8, G c_0..c_8, B c_0..c_8]``.

    Raises:
        ShapeError: ``sh`` is not ``(B, 9, 3)``.

    Shape:
        - Input: :math:`(B, 9, 3)`
        - Output: :math:`(B, 27)`

    Convention:
        Source: https://github.com/senguptaumd/SfSNet: ``SfSNet_train/python/Shading_Layer.py`` and
        ``functions/normal_harmonics.m`` / ``lambertian_attenuation.m`` (basis, order, ``att``),
        ``SfSNet_train/sfsnet_train.prototxt`` (the ``ChangeFormLayer`` turns Caffe's BGR normals, albedo
        and image into RGB before ``recon = shading * albedo``, so the first 9 values light R, and the
        normal's x, y, z are the R, G, B of the normal map), ``test_SfSNet.m`` / ``create_shading_recon.m``
        (``light_out(1:9)`` shades R).

        Axes: the repository states no frame. ``x`` along image rows (down), ``y`` along columns (right) and
        ``z`` toward the viewer is what its Python demo uses to render the lighting on a sphere
        (``spherical_harmonics.py``, ``get_sphere_normals``: ``x = (row - c) / r``, ``y = (col - c) / r``,
        ``z = +sqrt(1 - x^2 - y^2)``) and what DPR's ``utils/utils_normal.py`` draws as "the sfs lighting
        coordinate". Uncertain: not checked against SfSNet's released normal maps.

        Uncertain: the absolute scale; SfSNet fits sRGB-encoded images divided by 255 (not linearised).

    Examples:
        >>> sh = torch.zeros(1, 9, 3)
        >>> sh[:, 1] = 1.0  # light from +Y (up) is light from SfSNet's -x (coefficient 2, negative)
        >>> [round(v, 4) + 0.0 for v in sh_to_sfsnet(sh)[0, :9].tolist()]  # red; + 0.0 turns -0.0 into 0.0
        [0.0, 0.0, -0.3183, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]
    """
    check_tensor(sh, "sh", ["B", "9", "3"])
    light = sh.index_select(1, _index(_SFSNET_FROM_SPEC, sh)) * (_const(_SFSNET_SIGN, sh) / math.pi)
    return light.transpose(1, 2).reshape(sh.shape[0], 27)


def sh_from_sfsnet(light: torch.Tensor) -> torch.Tensor:
    r"""Convert SfSNet's 27 lighting values to our SH lighting; the inverse of :func:`sh_to_sfsnet`.

    Returns our lighting under which a white Lambertian surface shows SfSNet's shading of ``light``
    (``L = pi *`` a signed permutation of each channel's 9 values; see :func:`sh_to_sfsnet` for the
    convention and its sources). Divide by ``pi`` to read ``light`` as environment-map radiance instead.

    Args:
        light: ``(B, 27)`` SfSNet ``fc_light`` (R, then G, then B).

    Returns:
        ``(B, 9, 3)`` our SH lighting.

    Raises:
        ShapeError: ``light`` is not ``(B, 27)``.

    Shape:
        - Input: :math:`(B, 27)`
        - Output: :math:`(B, 9, 3)`

    Convention:
        docs/conventions.rst, "Spherical harmonics" (our order and frame) and "Units of lighting"; the other
        layout as in :func:`sh_to_sfsnet`.

    Examples:
        >>> light = torch.zeros(1, 27)
        >>> light[:, 1] = 1.0  # SfSNet's z of the red channel: light from the camera side (our +Z)
        >>> (sh_from_sfsnet(light)[0, :, 0] / math.pi).round(decimals=4) + 0.0  # the red channel
        tensor([0., 0., 1., 0., 0., 0., 0., 0., 0.])
    """
    check_tensor(light, "light", ["B", "27"])
    c = light.reshape(light.shape[0], 3, 9).transpose(1, 2)  # (B, 9, 3), SfSNet order
    spec = c * (_const(_SFSNET_SIGN, light) * math.pi)
    return spec.index_select(1, _index(_SPEC_FROM_SFSNET, light))
