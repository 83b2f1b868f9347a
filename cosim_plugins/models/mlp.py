"""The paper's multilayer perceptron (Sec. II-C, Table I): 9-10-10-6, 276 parameters.

Inputs: position (mm), velocity (mm/s) and the command applied next (Hz);
outputs: the state change x_{i+1} - x_i (deltas are far better conditioned
than absolute next states under min-max scaling). Both sides are min-max
scaled to [0, 1] on the training split. Trained in torch (Adam, MSE, 80/20
split, seeded and deterministic); the weights are exported to numpy, which
does all inference.
"""

from __future__ import annotations

import time

import numpy as np

from cosim.contract.errors import UserError
from cosim_plugins.identify.model import Model

LAYERS = (9, 10, 10, 6)


class MLPModel(Model):
    """9-10-10-6 ReLU MLP predicting state deltas; see module doc."""

    name = "mlp"
    version = 1

    def __init__(self, epochs=100, batch_size=2048, lr=3e-3, seed=0, test_frac=0.2, max_time_s=None):
        super().__init__(epochs=epochs, batch_size=batch_size, lr=lr, seed=seed, test_frac=test_frac,
                         max_time_s=max_time_s)
        self.weights: list[np.ndarray] = []
        self.biases: list[np.ndarray] = []
        self.scaling: dict[str, np.ndarray] = {}
        self.history: dict = {}

    # ------------------------------------------------------------ fitting

    def fit(self, dataset) -> "MLPModel":
        import torch  # imported before the clock starts

        t0 = time.perf_counter()
        opt = self.options
        train_i, test_i = dataset.split_pairs(1.0 - opt["test_frac"], seed=opt["seed"])
        if len(train_i) < 50:
            raise UserError(f"mlp fit: only {len(train_i)} training pairs; need at least 50")
        Xa, Ua, Xna = dataset.pairs(train_i)
        inp = np.concatenate([Xa, Ua], axis=1)
        out = Xna - Xa
        self.scaling = {"in_lo": inp.min(0), "in_hi": inp.max(0), "out_lo": out.min(0), "out_hi": out.max(0)}
        Xt, Yt = self._scale_in(inp), self._scale_out(out)
        Xb, Ub, Xnb = dataset.pairs(test_i)
        Xv = self._scale_in(np.concatenate([Xb, Ub], axis=1))
        Yv = self._scale_out(Xnb - Xb)

        threads, determ = torch.get_num_threads(), torch.are_deterministic_algorithms_enabled()
        torch.set_num_threads(1)  # a 9-10-10-6 net gains nothing from 2 threads, and loses a lot on a busy machine
        torch.use_deterministic_algorithms(True)
        torch.set_flush_denormal(True)  # Adam's second moments go denormal: 10x slower without this
        try:
            net, hist = _train(torch, Xt, Yt, Xv, Yv, opt, self._report)
        finally:
            torch.set_num_threads(threads)
            torch.use_deterministic_algorithms(determ)
            torch.set_flush_denormal(False)
        layers = [m for m in net if isinstance(m, torch.nn.Linear)]
        self.weights = [m.weight.detach().numpy().T.astype(float).copy() for m in layers]
        self.biases = [m.bias.detach().numpy().astype(float).copy() for m in layers]
        self.history = hist
        self.dt_s = dataset.dt_s
        self._prepare()
        self.train_time_s = time.perf_counter() - t0
        return self

    def _scale_in(self, z):
        lo, hi = self.scaling["in_lo"], self.scaling["in_hi"]
        return (z - lo) / np.where(hi > lo, hi - lo, 1.0)

    def _scale_out(self, y):
        lo, hi = self.scaling["out_lo"], self.scaling["out_hi"]
        return (y - lo) / np.where(hi > lo, hi - lo, 1.0)

    # ------------------------------------------------------------ inference

    def _step(self, x, u):
        h = (np.concatenate([x, u], axis=1) - self._in_lo) * self._in_inv
        W, b = self.weights, self.biases
        h = np.maximum(h @ W[0] + b[0], 0.0)
        h = np.maximum(h @ W[1] + b[1], 0.0)
        return x + (h @ W[2] + b[2]) * self._out_span + self.scaling["out_lo"]

    def _prepare(self):
        """Precompute the scaling factors used by :meth:`_step`."""
        sc = self.scaling
        self._in_lo = sc["in_lo"]
        self._in_inv = 1.0 / np.where(sc["in_hi"] > sc["in_lo"], sc["in_hi"] - sc["in_lo"], 1.0)
        self._out_span = np.where(sc["out_hi"] > sc["out_lo"], sc["out_hi"] - sc["out_lo"], 1.0)

    # ------------------------------------------------------------ reports and files

    @property
    def n_params(self) -> int:
        return sum(a * b + b for a, b in zip(LAYERS[:-1], LAYERS[1:]))

    def params(self) -> dict:
        return {"layers": list(LAYERS), "output": "state delta", **{k: v for k, v in self.history.items()}}

    def _state(self):
        arrays = {f"W{i}": w for i, w in enumerate(self.weights)}
        arrays |= {f"b{i}": b for i, b in enumerate(self.biases)}
        arrays |= {f"scale_{k}": v for k, v in self.scaling.items()}
        return {"history": self.history}, arrays

    def _restore(self, meta, arrays):
        n = len(LAYERS) - 1
        self.weights = [np.asarray(arrays[f"W{i}"], dtype=float) for i in range(n)]
        self.biases = [np.asarray(arrays[f"b{i}"], dtype=float) for i in range(n)]
        self.scaling = {k[6:]: np.asarray(v, dtype=float) for k, v in arrays.items() if k.startswith("scale_")}
        self.history = meta.get("history", {})
        self._prepare()


def _train(torch, Xt, Yt, Xv, Yv, opt, report):
    """Adam on MSE with shuffled minibatches; returns (net, history dict)."""
    torch.manual_seed(opt["seed"])
    gen = torch.Generator().manual_seed(opt["seed"])
    layers = []
    for i, (a, b) in enumerate(zip(LAYERS[:-1], LAYERS[1:])):
        layers.append(torch.nn.Linear(a, b))
        if i < len(LAYERS) - 2:
            layers.append(torch.nn.ReLU())
    net = torch.nn.Sequential(*layers)
    f32 = lambda a: torch.from_numpy(np.ascontiguousarray(a, dtype=np.float32))  # noqa: E731
    xt, yt, xv, yv = f32(Xt), f32(Yt), f32(Xv), f32(Yv)
    adam = torch.optim.Adam(net.parameters(), lr=opt["lr"], foreach=True)
    epochs = int(opt["epochs"])
    bs = int(min(opt["batch_size"], max(128, len(Xt) // 32)))  # at least ~32 steps per epoch
    sched = torch.optim.lr_scheduler.CosineAnnealingLR(adam, T_max=epochs, eta_min=opt["lr"] * 0.05)
    loss_fn = torch.nn.MSELoss()
    t0 = time.perf_counter()
    n = len(xt)
    done = 0
    for epoch in range(epochs):
        perm = torch.randperm(n, generator=gen)
        for s in range(0, n, bs):
            j = perm[s : s + bs]
            adam.zero_grad(set_to_none=True)
            loss = loss_fn(net(xt[j]), yt[j])
            loss.backward()
            adam.step()
        sched.step()
        done = epoch + 1
        if done % 25 == 0 or done == epochs:
            report(f"mlp: epoch {done}/{epochs}, train mse {loss.item():.3g}")
        if opt["max_time_s"] is not None and time.perf_counter() - t0 > opt["max_time_s"]:
            report(f"mlp: time budget reached after {done} epochs")
            break
    with torch.no_grad():
        train_mse = float(loss_fn(net(xt), yt))
        test_mse = float(loss_fn(net(xv), yv)) if len(xv) else float("nan")
    return net, {"epochs": done, "batch_size": bs, "train_mse_scaled": train_mse, "test_mse_scaled": test_mse,
                 "n_train": int(n), "n_test": int(len(xv))}
