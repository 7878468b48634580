"""A plain numpy re-statement of gsplat's world normalisation, the reference for r360gpu.io.frames.

It follows gsplat's ``examples/datasets/normalize.py`` (``similarity_from_cameras``,
``align_principal_axes``, ``transform_points``, ``transform_cameras``) and the
``normalize`` branch of ``examples/datasets/colmap.py``'s ``Parser`` (gsplat
commit 90d7b4b, 1.5.2 and later: with the "up side down" turn), step by step,
as the tests' independent reading of it.  Inputs: camera-to-world matrices
(N, 4, 4) in OpenCV axes, sorted by image name, and the sparse points (M, 3)
as float32, by point id.
"""
from __future__ import annotations

import numpy as np


def similarity_from_cameras(c2w):
    t = c2w[:, :3, 3]
    R = c2w[:, :3, :3]
    ups = np.sum(R * np.array([0, -1.0, 0]), axis=-1)
    world_up = np.mean(ups, axis=0)
    world_up /= np.linalg.norm(world_up)
    up_camspace = np.array([0.0, -1.0, 0.0])
    c = (up_camspace * world_up).sum()
    cross = np.cross(world_up, up_camspace)
    skew = np.array([[0.0, -cross[2], cross[1]], [cross[2], 0.0, -cross[0]], [-cross[1], cross[0], 0.0]])
    R_align = np.eye(3) + skew + (skew @ skew) * 1 / (1 + c)
    R = R_align @ R
    fwds = np.sum(R * np.array([0, 0.0, 1.0]), axis=-1)
    t = (R_align @ t[..., None])[..., 0]
    nearest = t + (fwds * -t).sum(-1)[:, None] * fwds
    translate = -np.median(nearest, axis=0)
    transform = np.eye(4)
    transform[:3, 3] = translate
    transform[:3, :3] = R_align
    scale = 1.0 / np.median(np.linalg.norm(t + translate, axis=-1))
    transform[:3, :] *= scale
    return transform


def align_principal_axes(point_cloud):
    centroid = np.median(point_cloud, axis=0)
    translated = point_cloud - centroid
    covariance = np.cov(translated, rowvar=False)
    eigenvalues, eigenvectors = np.linalg.eigh(covariance)
    eigenvectors = eigenvectors[:, eigenvalues.argsort()[::-1]]
    if np.linalg.det(eigenvectors) < 0:
        eigenvectors[:, 0] *= -1
    rotation = eigenvectors.T
    transform = np.eye(4)
    transform[:3, :3] = rotation
    transform[:3, 3] = -rotation @ centroid
    return transform


def transform_points(matrix, points):
    return points @ matrix[:3, :3].T + matrix[:3, 3]


def transform_cameras(matrix, camtoworlds):
    camtoworlds = np.einsum("nij, ki -> nkj", camtoworlds, matrix)
    scaling = np.linalg.norm(camtoworlds[:, 0, :3], axis=1)
    camtoworlds[:, :3, :3] = camtoworlds[:, :3, :3] / scaling[:, None, None]
    return camtoworlds


def normalize_world(camtoworlds, points, flip: bool = True):
    """(camtoworlds, points, transform) after gsplat's Parser(normalize=True)."""
    T1 = similarity_from_cameras(camtoworlds)
    camtoworlds = transform_cameras(T1, camtoworlds)
    points = transform_points(T1, points)
    T2 = align_principal_axes(points)
    camtoworlds = transform_cameras(T2, camtoworlds)
    points = transform_points(T2, points)
    transform = T2 @ T1
    if flip and np.median(points[:, 2]) > np.mean(points[:, 2]):
        T3 = np.array([[1.0, 0, 0, 0], [0, -1.0, 0, 0], [0, 0, -1.0, 0], [0, 0, 0, 1.0]])
        camtoworlds = transform_cameras(T3, camtoworlds)
        points = transform_points(T3, points)
        transform = T3 @ transform
    return camtoworlds, points, transform
