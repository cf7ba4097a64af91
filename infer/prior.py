"""Discriminative shared-space prior of the DS-GPLVM (Eq. 4-6) and its default class labels.

Everything works from per-view Gram matrices Y Yᵀ (N, N), so a 4.4 M-dimensional 3D view costs no more
than its Gram.
"""

import numpy as np


def distances_from_gram(gram):
    """Squared Euclidean distances between the rows of Y, from G = Y Yᵀ (N, N) -> (N, N), >= 0."""
    sq = np.diag(gram)
    return np.maximum(sq[:, None] + sq[None, :] - 2.0 * gram, 0.0)


def mean_squared_distance(d2):
    """t^(v) of Eq. 4: mean squared distance over pairs i != j (1.0 if there is no spread at all)."""
    n = len(d2)
    if n < 2:
        return 1.0
    t = d2.sum() / (n * (n - 1))
    return float(t) if t > 0 else 1.0


def normalized_laplacian(gram, labels):
    """L_N = D^-½ (D − W) D^-½ for one view (Eq. 4 and the normalisation below it).

    W_ij = exp(-|y_i − y_j|² / t) for i != j of the same class, t the mean squared distance.
    A node with no same-class neighbour (D_ii = 0) gets a zero row: the prior leaves it alone.
    """
    d2 = distances_from_gram(gram)
    same = labels[:, None] == labels[None, :]
    np.fill_diagonal(same, False)
    w = np.where(same, np.exp(-d2 / mean_squared_distance(d2)), 0.0)
    degree = w.sum(1)
    inv_sqrt = np.where(degree > 0, 1.0 / np.sqrt(np.where(degree > 0, degree, 1.0)), 0.0)
    lap = np.diag((degree > 0).astype(float)) - inv_sqrt[:, None] * w * inv_sqrt[None, :]
    return lap


def joint_laplacian(grams, labels, xi):
    """L̃ = Σ_v L_N^(v) + ξ I (Eq. 5). grams: list of (N, N). labels: (N,) ints. -> (N, N)."""
    labels = np.asarray(labels)
    lap = sum(normalized_laplacian(g, labels) for g in grams)
    return lap + xi * np.eye(len(labels))


def spectral_labels(grams, n_classes=2, seed=0):
    """Class labels by spectral clustering of the training BRDFs (the paper's default), (N,) ints.

    Affinity exp(-Σ_v d2_v / t_v / V): each view's squared distances normalised by its mean so that no
    view dominates. Fewer than 2·n_classes samples -> all in one class.
    """
    # imported here: sklearn.cluster adds 2.2 s to every `import infer` (python -X importtime,
    # 2 shared cores) and only training with labels clusters
    from sklearn.cluster import SpectralClustering

    n = len(grams[0])
    if n < 2 * n_classes:
        return np.zeros(n, dtype=int)
    scaled = sum(distances_from_gram(g) / mean_squared_distance(distances_from_gram(g))
                 for g in grams) / len(grams)
    affinity = np.exp(-scaled)
    model = SpectralClustering(n_clusters=n_classes, affinity="precomputed", random_state=seed)
    return model.fit_predict(affinity).astype(int)


def prior_energy(latent, laplacian, beta):
    """β/2 tr(Xᵀ L̃ X) of Eq. 6-7 and its gradient wrt X: (float, (N, q))."""
    lx = laplacian @ latent
    return 0.5 * beta * float(np.sum(latent * lx)), beta * lx
