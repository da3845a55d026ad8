"""DHN — Denoising Hamiltonian Network (Deng et al. 2025), at a size that trains on a laptop CPU.

What is kept from the original:

- block-wise *discrete* Hamiltonians over windows of ``S`` consecutive states, ``q = (x, y)``,
  ``p = v``: the right Hamiltonian ``H⁺(q_k, p_{k+1})`` gives ``q_{k+1} = q_k + ∂H⁺/∂p_{k+1}``,
  ``p_k = p_{k+1} + ∂H⁺/∂q_k``; the left one ``H⁻(p_k, q_{k+1})`` gives ``q_k = q_{k+1} − ∂H⁻/∂p_k``,
  ``p_{k+1} = p_k − ∂H⁻/∂q_{k+1}`` — each applied to a source block and the block shifted by one;
- the masked / denoising objective: the last entries of the target block are masked and replaced
  by Gaussian noise with a random mask level that the network sees, and must be reconstructed;
  plus the plain equation-of-motion loss of both Hamiltonians;
- a global latent code per trajectory, learned as a free parameter (auto-decoder); a new
  trajectory's code is fitted with the networks frozen;
- autoregressive rollout: ``q_{k+1}`` from ``H⁺`` with the newest momentum masked, then
  ``p_{k+1}`` from ``H⁻``.

Where it departs (documented, to fit a 2-core CPU and this problem): MLPs over the flattened block
instead of transformers; block step 1; one denoising pass at inference instead of iterated
denoising; the known external force at the block's times is an extra (non-differentiated) input,
since the original systems are unforced; and the rollout needs a prefix of ``S + 1`` observed
(clean) states — ``S·dt`` seconds more than the single initial state the other models get — from
which the test trajectory's latent code is fitted.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optax

from fhnn.config import Config, check_nonnegative, check_positive, frozen_config
from fhnn.data.dataset import Split
from fhnn.models.base import AbstractModel

Array = jax.Array


@frozen_config
class DHNConfig(Config):
    """Size and objective of a DHN.

    Attributes:
        width, depth: MLP size of each Hamiltonian.
        block: states per block ``S``.
        latent: size of the per-trajectory code.
        w_denoise: weight of the denoising loss (the equation-of-motion loss has weight 1).
        code_decay: weight of ``mean ‖z‖²`` (keeps the auto-decoder codes bounded).
        fit_steps, fit_lr: Adam steps and rate for a new trajectory's code.
    """

    config_name = "dhn"

    width: int = 64
    depth: int = 2
    block: int = 4
    latent: int = 8
    w_denoise: float = 1.0
    code_decay: float = 1e-4
    fit_steps: int = 200
    fit_lr: float = 3e-2

    def validate(self) -> None:
        check_positive(self, "width", "depth", "block", "latent", "fit_steps", "fit_lr")
        check_nonnegative(self, "w_denoise", "code_decay")


class DHN(AbstractModel):
    """Discrete, block-wise Hamiltonian model; not a continuous vector field (see module doc)."""

    h_plus: eqx.nn.MLP
    h_minus: eqx.nn.MLP
    codes: Array  # (N_train, latent)
    scale_q: tuple[float, float] = eqx.field(static=True)
    scale_p: tuple[float, float] = eqx.field(static=True)
    scale_f: float = eqx.field(static=True)
    step_scale: tuple[float, float, float, float] = eqx.field(static=True)
    energy: float = eqx.field(static=True)
    block: int = eqx.field(static=True)
    w_denoise: float = eqx.field(static=True)
    code_decay: float = eqx.field(static=True)
    fit_steps: int = eqx.field(static=True)
    fit_lr: float = eqx.field(static=True)

    @property
    def window(self) -> int:
        return self.block + 1

    # -- the two discrete Hamiltonians -------------------------------------------------------------
    def _h(self, mlp: eqx.nn.MLP, a: Array, b: Array, ma: Array, mb: Array, f: Array, z: Array) -> Array:
        inp = jnp.concatenate([a.ravel(), b.ravel(), ma.ravel(), mb.ravel(), f.ravel() / self.scale_f, z])
        return self.energy * mlp(inp)[0]

    def plus(self, q: Array, p_next: Array, mq: Array, mp: Array, f: Array, z: Array) -> tuple[Array, Array]:
        """Right Hamiltonian: ``(q_{k+1}, p_k)`` predicted from ``(q_k, p_{k+1})`` blocks ``(S, 2)``."""
        qn, pn = q / jnp.asarray(self.scale_q), p_next / jnp.asarray(self.scale_p)
        g_q, g_p = jax.grad(lambda a, b: self._h(self.h_plus, a, b, mq, mp, f, z), argnums=(0, 1))(qn, pn)
        return q + g_p / jnp.asarray(self.scale_p), p_next + g_q / jnp.asarray(self.scale_q)

    def minus(self, p: Array, q_next: Array, mp: Array, mq: Array, f: Array, z: Array) -> tuple[Array, Array]:
        """Left Hamiltonian: ``(q_k, p_{k+1})`` predicted from ``(p_k, q_{k+1})`` blocks ``(S, 2)``."""
        pn, qn = p / jnp.asarray(self.scale_p), q_next / jnp.asarray(self.scale_q)
        g_p, g_q = jax.grad(lambda a, b: self._h(self.h_minus, a, b, mp, mq, f, z), argnums=(0, 1))(pn, qn)
        return q_next - g_p / jnp.asarray(self.scale_p), p - g_q / jnp.asarray(self.scale_q)

    # -- training objective ------------------------------------------------------------------------
    def _window_losses(
        self, s: Array, f: Array, z: Array, key: Array, step_scale: Array
    ) -> tuple[Array, Array]:
        S = self.block
        q_src, p_src, q_tgt, p_tgt = s[:S, :2], s[:S, 2:], s[1:, :2], s[1:, 2:]
        f_blk = f[: S + 1]
        sq, sp = step_scale[:2], step_scale[2:]
        ones = jnp.ones((S, 2))
        err = lambda a, b, sc: jnp.mean(((a - b) / sc) ** 2)  # noqa: E731
        qt, ps = self.plus(q_src, p_tgt, ones, ones, f_blk, z)
        qs, pt = self.minus(p_src, q_tgt, ones, ones, f_blk, z)
        eom = err(qt, q_tgt, sq) + err(ps, p_src, sp) + err(qs, q_src, sq) + err(pt, p_tgt, sp)
        # denoising: the newest target entries are unknown; they enter as noise at a random mask level
        k1, k2, k3, k4 = jax.random.split(key, 4)
        known = jnp.ones((S, 2)).at[-1].set(0.0)
        level_p = known + jax.random.uniform(k1, (1, 1)) * (1 - known)
        level_q = known + jax.random.uniform(k2, (1, 1)) * (1 - known)
        noisy_p = p_tgt * level_p + jax.random.normal(k3, (S, 2)) * jnp.asarray(self.scale_p) * (1 - level_p)
        noisy_q = q_tgt * level_q + jax.random.normal(k4, (S, 2)) * jnp.asarray(self.scale_q) * (1 - level_q)
        qt_d, _ = self.plus(q_src, noisy_p, ones, level_p, f_blk, z)
        _, pt_d = self.minus(p_src, noisy_q, ones, level_q, f_blk, z)
        denoise = err(qt_d[-1], q_tgt[-1], sq) + err(pt_d[-1], p_tgt[-1], sp)
        return eom, denoise

    def loss_terms(self, batch: dict[str, Array], scales: tuple[Array, Array]) -> dict[str, Array]:
        _, step_scale = scales
        forces = batch["forces"]
        z = self.codes[batch["traj"]]
        keys = jax.random.split(batch["key"], batch["s"].shape[0])
        eom, denoise = jax.vmap(self._window_losses, in_axes=(0, 0, 0, 0, None))(
            batch["s"], forces, z, keys, step_scale
        )
        return {
            "eom": jnp.mean(eom),
            "denoise": self.w_denoise * jnp.mean(denoise),
            "codes": self.code_decay * jnp.mean(jnp.sum(self.codes**2, axis=-1)),
        }

    # -- autoregressive rollout --------------------------------------------------------------------
    def fit_code(self, prefix: Array, forces: Array, step_scale: Array) -> Array:
        """A new trajectory's code from its first ``S + 1`` states ``(S+1, 4)`` (networks frozen)."""
        opt = optax.adam(self.fit_lr)
        z0 = jnp.mean(self.codes, axis=0)

        def loss(z: Array) -> Array:
            eom, _ = self._window_losses(prefix, forces, z, jax.random.PRNGKey(0), step_scale)
            return eom

        def body(carry: tuple[Array, optax.OptState], _: None) -> tuple[tuple[Array, optax.OptState], None]:
            z, st = carry
            updates, st = opt.update(jax.grad(loss)(z), st)
            return (optax.apply_updates(z, updates), st), None

        (z, _), _ = jax.lax.scan(body, (z0, opt.init(z0)), None, length=self.fit_steps)
        return z

    def generate(self, prefix: Array, forces: Array, z: Array) -> Array:
        """States at every sample time: the prefix ``(S+1, 4)``, then one step at a time.

        ``forces``: ``F_ext`` at every sample time, ``(T, 2)``. Returns ``(T, 4)``.
        """
        S = self.block
        T = forces.shape[0]
        ones = jnp.ones((S, 2))
        known = ones.at[-1].set(0.0)

        def step(blk: Array, k: Array) -> tuple[Array, Array]:
            # blk: the newest S states, ending at time index k
            f_blk = jax.lax.dynamic_slice_in_dim(forces, k - S + 1, S + 1)
            p_tgt = jnp.concatenate([blk[1:, 2:], jnp.zeros((1, 2))])
            q_tgt, _ = self.plus(blk[:, :2], p_tgt, ones, known, f_blk, z)
            _, p_next = self.minus(blk[:, 2:], q_tgt, ones, ones, f_blk, z)
            new = jnp.concatenate([q_tgt[-1], p_next[-1]])
            return jnp.concatenate([blk[1:], new[None]]), new

        ks = jnp.arange(S, T - 1)
        _, rest = jax.lax.scan(step, prefix[1:], ks)
        return jnp.concatenate([prefix, rest])[:T]

    def predict(
        self, start: np.ndarray, split: Split, t: np.ndarray, rtol: float, atol: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """Autoregressive rollout (``rtol``/``atol`` unused): each trajectory's code is fitted to
        its first ``S + 1`` states of ``start``, then one block step at a time."""
        T = t.size
        S = self.block
        states = jnp.asarray(start[:, : S + 1])
        forces = jnp.asarray(split.forces[:, : max(T, S + 1)])
        step_scale = jnp.asarray(self.step_scale)

        @eqx.filter_jit
        def one(model: DHN, prefix: Array, f: Array) -> Array:
            z = model.fit_code(prefix, f[: S + 1], step_scale)
            return model.generate(prefix, f, z)

        out = np.stack([np.asarray(one(self, states[i], forces[i])) for i in range(split.n_traj)])[:, :T]
        return out, np.ones(split.n_traj, dtype=bool)


def build_dhn(config: DHNConfig, stats: dict, n_traj: int, key: Array) -> DHN:
    """A fresh DHN with ``n_traj`` training codes; ``stats`` as for the other baselines
    (:func:`~fhnn.models.baselines.data_statistics`), including ``step_std``, the per-component std
    of one-step increments that scales a new trajectory's code fit."""
    S = config.block
    n_in = 4 * 2 * S + 2 * (S + 1) + config.latent
    k1, k2, k3 = jax.random.split(key, 3)
    make = lambda k: eqx.nn.MLP(n_in, 1, config.width, config.depth, activation=jnp.tanh, key=k)  # noqa: E731
    std = stats["state_std"]
    step = stats["step_std"]
    return DHN(
        h_plus=make(k1),
        h_minus=make(k2),
        codes=0.01 * jax.random.normal(k3, (n_traj, config.latent)),
        scale_q=(std[0], std[1]),
        scale_p=(std[2], std[3]),
        scale_f=stats["force_std"],
        step_scale=tuple(float(x) for x in step),
        energy=float(np.mean(step[:2]) * np.mean(std[2:])),
        block=S,
        w_denoise=config.w_denoise,
        code_decay=config.code_decay,
        fit_steps=config.fit_steps,
        fit_lr=config.fit_lr,
    )
