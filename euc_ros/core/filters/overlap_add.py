"""Overlap-add convolutions of one signal with several kernels, its transform made once.

A Savitzky-Golay filter convolves each signal with the value's and both derivatives' kernels, and the masked fits
(:mod:`~euc_ros.core.filters.masked_savgol`) convolve the recorded mask with every product of two basis
polynomials: one input, many kernels of one length. :func:`oaconvolve_many` gives each convolution exactly as
``scipy.signal.oaconvolve`` does, with the input's blocks and their transforms made once.
"""
from __future__ import annotations

import math

import numpy as np


def oaconvolve_many(x: np.ndarray, kernels, axes):
    """Full convolutions of one array with kernels of one shape, each ``scipy.signal.oaconvolve``'s, number for number.

    ``oaconvolve(x, k, mode="full", axes=axes)`` for every ``k`` of ``kernels``, made one at a time (a generator):
    the steps of scipy's overlap-add that depend on ``x`` alone (its padding, its blocks and their transforms) are
    made once for all kernels, and every step that involves a kernel is scipy's own, on arrays of the same shapes,
    so each result is the one ``oaconvolve`` gives (``test_overlap_add`` compares them bit for bit). The cases
    scipy does not split into blocks (equal shapes, one block, empty or complex arrays) are handed to it.

    Parameters
    ----------
    x : numpy.ndarray
        The input, float64.
    kernels : sequence of numpy.ndarray
        Kernels of one shape, with ``x``'s number of dimensions.
    axes : int or sequence of int
        The axes convolved along.

    Yields
    ------
    numpy.ndarray
        The full convolution of ``x`` with each kernel, in order.
    """
    from scipy import fft as sp_fft
    from scipy.signal import oaconvolve
    from scipy.signal._signaltools import _calc_oa_lens

    x = np.asarray(x)
    kernels = [np.asarray(k) for k in kernels]
    s1 = x.shape
    s2 = kernels[0].shape if kernels else s1
    axes_ = sorted(a % x.ndim for a in (np.atleast_1d(axes).tolist() if x.ndim else []))
    axes_ = [a for a in axes_ if s1[a] != 1 and s2[a] != 1]
    plain = (x.ndim == 0 or x.dtype != np.float64 or x.size == 0 or s1 == s2 or not axes_
             or any(k.shape != s2 or k.dtype != np.float64 or k.ndim != x.ndim for k in kernels))
    sizes = None if plain else [(-1, -1, s1[i], s2[i]) if i not in axes_ else _calc_oa_lens(s1[i], s2[i])
                                for i in range(x.ndim)]
    if plain or all(sz[2] == s1[i] and sz[3] == s2[i] for i, sz in enumerate(sizes)):
        for k in kernels:
            yield oaconvolve(x, k, mode="full", axes=axes)
        return
    block_size, overlaps, in1_step, in2_step = zip(*sizes)
    shape_final = [None if i not in axes_ else s1[i] + s2[i] - 1 for i in range(x.ndim)]
    nsteps1, nsteps2, pad1, pad2 = [], [], [], []
    for i in range(x.ndim):
        if i not in axes_:
            pad1.append((0, 0))
            pad2.append((0, 0))
            continue
        steps = []
        for s, step, pads in ((s1[i], in1_step[i], pad1), (s2[i], in2_step[i], pad2)):
            if s > step:
                nstep = math.ceil((s + 1) / step)
                if (block_size[i] - overlaps[i]) * nstep < shape_final[i]:
                    nstep += 1
                pads.append((0, nstep * step - s))
            else:
                nstep = 1
                pads.append((0, 0))
            steps.append(nstep)
        nsteps1.append(steps[0])
        nsteps2.append(steps[1])
    if any(p != (0, 0) for p in pad1):
        x = np.pad(x, pad1, mode="constant", constant_values=0)
    split_axes = [ax + i for i, ax in enumerate(axes_)]
    fft_axes = [ax + 1 for ax in split_axes]
    shape1, shape2 = list(in1_step), list(in2_step)
    for i, ax in enumerate(split_axes):
        shape1.insert(ax, nsteps1[i])
        shape2.insert(ax, nsteps2[i])
    fft_shape = [block_size[i] for i in axes_]
    spectrum = sp_fft.rfftn(np.reshape(x, tuple(shape1)), fft_shape, axes=fft_axes)   # the input's, made once
    del x
    for k in kernels:
        if any(p != (0, 0) for p in pad2):
            k = np.pad(k, pad2, mode="constant", constant_values=0)
        ret = sp_fft.irfftn(spectrum * sp_fft.rfftn(np.reshape(k, tuple(shape2)), fft_shape, axes=fft_axes),
                            fft_shape, axes=fft_axes)
        for ax, ax_fft, ax_split in zip(axes_, fft_axes, split_axes):       # the overlap-add, as scipy's
            overlap = overlaps[ax]
            if overlap is None:
                continue
            cut = ret.shape[ax_fft] - overlap
            overpart = np.swapaxes(np.swapaxes(ret, ax_fft, 0)[cut:], ax_fft, 0)
            overpart = np.swapaxes(np.swapaxes(overpart, ax_split, 0)[:overpart.shape[ax_split] - 1], ax_split, 0)
            ret = np.swapaxes(np.swapaxes(ret, ax_fft, 0)[:cut], ax_fft, 0)
            head = np.swapaxes(np.swapaxes(ret, ax_fft, 0)[:overlap], ax_fft, 0)
            head = np.swapaxes(np.swapaxes(head, ax_split, 0)[1:], ax_split, 0)
            head += overpart
        shape_ret = [ret.shape[i] if i not in fft_axes else ret.shape[i] * ret.shape[i - 1]
                     for i in range(ret.ndim) if i not in split_axes]
        yield np.reshape(ret, tuple(shape_ret))[tuple(slice(s) for s in shape_final)]
        del ret
