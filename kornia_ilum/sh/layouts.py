r"""Converters between SPEC's SH lighting and the 27-float SH layouts of DECA, ARCore and WebXR.

Every converter is linear (a fixed permutation, sign and scale per coefficient), so round trips are exact
to rounding (bit-exact for ARCore / WebXR, whose conversion is only signs) and gradients pass through.

Convention:
    SPEC side: ``(B, 9, 3)`` radiance coefficients in the orthonormal real basis of
    :mod:`kornia_ilum.sh.harmonics` (SPEC order, no Condon-Shortley phase, frame +X right, +Y up, +Z toward
    the camera). A white Lambertian surface with normal ``n`` shows ``E(n) / pi`` where
    ``E = sum_lm A_l L_lm Y_lm(n)`` (:func:`~kornia_ilum.sh.sh_irradiance_at`).

    ===========  =========================  ==========================================  ==================
    layout       shape                      coefficient order                           frame
    ===========  =========================  ==========================================  ==================
    DECA         ``(B, 9, 3)``              ``1, x, y, z, xy, xz, yz, x2-y2, 3z2-1``    = SPEC
    ARCore       ``(B, 27)`` RGB per coeff  SPEC order, Condon-Shortley signs           ARCore world
    WebXR        ``(B, 27)`` RGB per coeff  identical to ARCore (aliases)               probe space
    ===========  =========================  ==========================================  ==================
"""

from __future__ import annotations

import math

import torch

from kornia_ilum.core.check import check_tensor

__all__ = [
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


def _const(values: tuple[float, ...], like: torch.Tensor) -> torch.Tensor:
    return torch.tensor(values, device=like.device, dtype=like.dtype)[:, None]


def _index(values: tuple[int, ...], like: torch.Tensor) -> torch.Tensor:
    return torch.tensor(values, device=like.device, dtype=torch.long)


def sh_to_deca(sh: torch.Tensor) -> torch.Tensor:
    r"""Convert SPEC SH lighting to DECA's ``light`` code.

    DECA (Feng et al. 2021, "Learning an Animatable Detailed 3D Face Model from In-The-Wild Images")
    shades a face as ``albedo * shading`` with
    ``shading(N) = sum_i light[i] * f_i * p_i(N)``, ``p = (1, x, y, z, xy, xz, yz, x^2 - y^2, 3 z^2 - 1)``
    and ``f = (1/sqrt(4 pi), A_1 sqrt(3/(4 pi)) [x3], A_2 * 3 sqrt(5/(12 pi)) [x3],
    A_2 * 3/2 sqrt(5/(12 pi)), A_2 * 1/2 sqrt(5/(4 pi)))``: the orthonormal constants times the
    Ramamoorthi-Hanrahan factors, except that band 0 lacks ``A_0 = pi``.

    This function returns the code for which DECA's ``shading`` equals ``E(n) / pi``, the value a white
    Lambertian surface shows under ``sh`` (SPEC.md, units): ``light[0] = L_00`` and
    ``light[i] = L_lm / pi`` for the other coefficients, reordered to DECA's basis order.

    Args:
        sh: ``(B, 9, 3)`` SPEC SH lighting.

    Returns:
        ``(B, 9, 3)`` DECA ``codedict['light']``.

    Convention:
        Source: ``decalib/utils/renderer.py`` of https://github.com/yfeng95/DECA (``SRenderY.__init__``,
        ``constant_factor``; ``SRenderY.add_SHlight``). The normals DECA shades with are FLAME-space vertex
        normals (``decalib/deca.py``, ``decode``: ``self.render(verts, trans_verts, albedo, light)``), and
        FLAME space under DECA's orthographic camera is SPEC's frame: ``batch_orth_proj`` only scales and
        shifts x, y; the renderer then flips y and z for rasterisation, and its visibility mask keeps
        normals whose flipped z is negative, i.e. outward normals facing +Z. No sign changes are needed.

        Uncertain: the absolute scale. DECA fits sRGB-encoded photographs without linearising them, so its
        light codes are in "sRGB-ish" units; and another reading of its code (``light`` as plain radiance
        coefficients, the missing ``pi`` in band 0 a slip) would drop the ``1 / pi`` on bands 1 and 2. The
        definition here reproduces DECA's shading exactly; the tests check it against DECA's formula.

    Examples:
        >>> sh = torch.zeros(1, 9, 3)
        >>> sh[:, 1] = 1.0  # light from +Y (SPEC coefficient (1, -1))
        >>> sh_to_deca(sh)[0, :, 0]  # lands on DECA's y coefficient, divided by pi
        tensor([0.0000, 0.0000, 0.3183, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000])
    """
    check_tensor(sh, "sh", ["B", "9", "3"])
    return sh.index_select(1, _index(_DECA_FROM_SPEC, sh)) * _const(_DECA_SCALE, sh)


def sh_from_deca(light: torch.Tensor) -> torch.Tensor:
    r"""Convert DECA's ``light`` code to SPEC SH lighting; the inverse of :func:`sh_to_deca`.

    Args:
        light: ``(B, 9, 3)`` DECA ``codedict['light']``.

    Returns:
        ``(B, 9, 3)`` SPEC SH lighting (see :func:`sh_to_deca` for the convention and its source).

    Examples:
        >>> light = torch.zeros(1, 9, 3)
        >>> light[:, 0] = 1.0
        >>> sh_from_deca(light)[0, 0]
        tensor([1., 1., 1.])
    """
    check_tensor(light, "light", ["B", "9", "3"])
    return (light / _const(_DECA_SCALE, light)).index_select(1, _index(_SPEC_FROM_DECA, light))


def sh_to_arcore(sh: torch.Tensor) -> torch.Tensor:
    r"""Convert SPEC SH lighting to ARCore's 27 floats (also WebXR's, see :func:`sh_to_webxr`).

    ARCore's ``LightEstimate.getEnvironmentalHdrAmbientSphericalHarmonics()`` (C:
    ``ArLightEstimate_getEnvironmentalHdrAmbientSphericalHarmonics``, ``out_coefficients_27``) returns 9
    coefficients x RGB, interleaved per coefficient (``[c0.r, c0.g, c0.b, c1.r, ...]``), in SPEC's
    ``(l, m)`` order. They are *radiance* coefficients in the orthonormal basis, but with the
    Condon-Shortley phase of Filament's SH (Filament's ``CubemapSH``), so the ``m = +-1`` functions of
    bands 1 and 2 (indices 1, 3, 5, 7) change sign: ``c_arcore = s * c_spec``,
    ``s = (+, -, +, -, +, -, +, -, +)``. A light from +Y gives a *negative* ``c_arcore[1]``.

    Args:
        sh: ``(B, 9, 3)`` SPEC SH lighting.

    Returns:
        ``(B, 27)`` ARCore coefficients.

    Convention:
        Source: the ARCore SDK sample ``samples/hello_ar_java`` of
        https://github.com/google-ar/arcore-android-sdk: ``sphericalHarmonicFactors`` =
        ``(0.282095, -0.325735, 0.325735, -0.325735, 0.273137, -0.273137, 0.078848, -0.273137, 0.136569)``
        (the SPEC constants times ``A_l / pi`` times the sign ``s``) multiply the ARCore coefficients, and
        ``shaders/environmental_hdr.frag`` evaluates them with the sign-free polynomials
        ``1, y, z, x, yx, yz, 3z^2 - 1, zx, x^2 - y^2`` of the world-space normal to get the Lambertian
        ``E(n) / pi``. The tests check that formula against :func:`~kornia_ilum.sh.sh_irradiance_at`.
        Babylon.js reads WebXR's array the same way (``Maths/sphericalPolynomial.ts``,
        ``updateFromHarmonics`` negates ``l1_1``, ``l11``, ``l2_1``, ``l21``).

        Frame: ARCore world space (right-handed, +Y up against gravity; cameras look along their -Z). It
        coincides with SPEC's frame when the camera's rotation in the world is the identity; otherwise
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
    r"""Convert ARCore's (or WebXR's) 27 floats to SPEC SH lighting; the inverse of :func:`sh_to_arcore`.

    Args:
        coefficients: ``(B, 27)`` coefficients, RGB interleaved per coefficient.

    Returns:
        ``(B, 9, 3)`` SPEC SH lighting (see :func:`sh_to_arcore` for the convention and its sources).

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
