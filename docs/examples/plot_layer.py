"""
The differentiable cage layer
=============================

The README's "Learned mode" names ``cagekit_learn.bind``: mean value coordinates in
torch, differentiable in the points and the cage. Here it is the layer of a small
optimisation: the shape is bound to its cage once, and the cage's vertices are fitted by
gradient descent so that the deformed shape matches a target (the shape stretched along
x, vertex for vertex), with a term that keeps the cage's edges from shearing. It runs
from the repository root, where ``data/example`` is.
"""

# sphinx_gallery_start_ignore
# ruff: noqa: E402 (the example follows after this hidden part)
import os as _os
from pathlib import Path as _Path

_os.chdir(_Path.cwd().parents[1])
# sphinx_gallery_end_ignore
import matplotlib.pyplot as plt
import torch

import cagekit_learn
from cagekit.io import load_mesh

V, F = load_mesh("data/example/shape.obj")
cage_v, cage_f = load_mesh("data/example/cage.obj")
points = torch.tensor(V)                       # (n, 3) float64
rest = torch.tensor(cage_v)                    # (k, 3)
binding = cagekit_learn.bind(points, rest, cage_f)
target = points * torch.tensor([1.6, 1.0, 1.0])
edges = torch.tensor(cage_f)[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)

cage = rest.clone().requires_grad_(True)
optimiser = torch.optim.Adam([cage], lr=0.02)
history = []
for _ in range(300):
    optimiser.zero_grad()
    fit = (binding.deform(cage) - target).square().sum(dim=1).mean()
    stretch = cage[edges[:, 0]] - cage[edges[:, 1]] - (rest[edges[:, 0]] - rest[edges[:, 1]])
    loss = fit + 1e-4 * stretch.square().sum(dim=1).mean()
    loss.backward()
    optimiser.step()
    history.append(fit.item())

print(f"mean squared error: {history[0]:.4f} at the start, {history[-1]:.2e} after "
      f"{len(history)} steps")

plt.figure(figsize=(5, 3))
plt.semilogy(history)
plt.xlabel("Adam step")
plt.ylabel("mean squared error")
plt.tight_layout()
