"""The PyTorch side of ``benchmarks/peer.py``: the peers of thrombojax's three models.

* MeshGraphNet: NVIDIA PhysicsNeMo's ``MeshGraphNet`` (PyG graph, ``torch_scatter`` sum),
  constructed from thrombojax's config (:class:`thrombojax.models.configs.MeshGraphNetConfig`):
  node input 5 (velocity, node-type one-hot), edge input 4 (``x_i - x_j``, its norm), output 3,
  every encoder / processor / decoder MLP ``hidden`` wide with ``mlp_layers`` hidden layers.
* Transolver: PhysicsNeMo's ``Transolver`` (irregular mesh, ``use_te=False``) fed Erwin's MPNN
  embedding (:class:`MPNNEmbedding`, written here from the equations in
  ``thrombojax/models/layers.py``), as the study did and as ``thrombojax/models/transolver.py``
  describes.
* Erwin: the official ``ErwinTransformer`` (``models/erwin.py`` of the checkout given by
  ``--erwin-src``; it builds its ball tree with ``balltree-erwin`` and its radius graph with
  ``torch_cluster.radius_graph`` itself) plus the prediction head of the official experiment
  wrappers (Linear, GELU, Linear), as ``thrombojax/models/erwin.py`` describes.

Every step builds the graph from the current positions with ``torch_cluster.radius_graph``
(same radius and neighbour cap as thrombojax; the official Erwin uses torch_cluster's default
cap, 32). Cases: ``step`` (graph + forward + integration, ``torch.inference_mode``),
``rollout`` (a Python loop of steps), ``forward`` (graph + forward), ``train`` (graph, forward,
masked MSE on the normalised acceleration of the clot nodes, backward, ``torch.optim.AdamW``
with the study's learning rate and weight decay 0.01). ``torch.set_num_threads(threads)``.

Run by the parent as ``python benchmarks/peer_torch.py SPEC_JSON`` (``benchmarks/peer_common.py``
describes the protocol).
"""

from __future__ import annotations

import importlib.metadata
import importlib.util
import json
import math
import os
import sys

import torch
from torch import nn

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from peer_common import STATS, Case, read_inputs, serve  # noqa: E402

__all__ = ["allow_cpu_torchvision", "MPNNEmbedding", "build_peer", "prepare", "versions"]

_TORCHVISION_OPS = None


def allow_cpu_torchvision() -> None:
    """Let the CUDA build of torchvision import on a CPU-only torch (PhysicsNeMo imports timm,
    which imports torchvision; neither model benchmarked here calls a torchvision op).

    torchvision's wheels are CUDA builds whose compiled ops do not load with a CPU torch;
    torchvision then skips its ops, except two fake-tensor registrations (``nms``, ``qnms``)
    that need the op to exist. Those two schemas are declared here, without kernels (calling
    them raises), when torchvision's ops library does not load. Does nothing when it loads.
    """
    global _TORCHVISION_OPS
    spec = importlib.util.find_spec("torchvision")
    if spec is None or _TORCHVISION_OPS is not None:
        return
    try:
        torch.ops.load_library(os.path.join(os.path.dirname(spec.origin), "_C.so"))
        return
    except OSError:
        pass
    _TORCHVISION_OPS = torch.library.Library("torchvision", "FRAGMENT")
    for op in ("nms", "qnms"):
        _TORCHVISION_OPS.define(f"{op}(Tensor dets, Tensor scores, float iou_threshold) -> Tensor")


def _radius_graph(pos: torch.Tensor, radius: float, k: int, loop: bool) -> torch.Tensor:
    """``[2, E]`` edges ``j -> i`` (row 0 sender j, row 1 receiver i), at most ``k`` per i."""
    import torch_cluster
    return torch_cluster.radius_graph(pos, r=radius, loop=loop, max_num_neighbors=k)


class MPNNEmbedding(nn.Module):
    """Erwin's MPNN embedding: ``h = W f``, then per step ``m_ij = LN(GELU(W_m [h_j, h_i,
    x_j - x_i]))``, ``m_i = mean_j m_ij``, ``h_i += LN(W_u [h_i, m_i])`` (edges ``j -> i``)."""

    def __init__(self, in_dim: int, dim: int, mp_steps: int):
        super().__init__()
        self.embed = nn.Linear(in_dim, dim)
        self.message = nn.ModuleList(
            nn.Sequential(nn.Linear(2 * dim + 3, dim), nn.GELU(), nn.LayerNorm(dim))
            for _ in range(mp_steps))
        self.update = nn.ModuleList(
            nn.Sequential(nn.Linear(2 * dim, dim), nn.LayerNorm(dim)) for _ in range(mp_steps))

    def forward(self, feats: torch.Tensor, pos: torch.Tensor, edges: torch.Tensor):
        src, dst = edges
        h = self.embed(feats)
        rel = pos[src] - pos[dst]
        count = torch.zeros(h.shape[0], 1, dtype=h.dtype).index_add_(
            0, dst, torch.ones(dst.shape[0], 1, dtype=h.dtype)).clamp(min=1)
        for message, update in zip(self.message, self.update, strict=True):
            msg = message(torch.cat([h[src], h[dst], rel], dim=-1))
            agg = torch.zeros_like(h).index_add_(0, dst, msg) / count
            h = h + update(torch.cat([h, agg], dim=-1))
        return h


class _MGN(nn.Module):
    """PhysicsNeMo MeshGraphNet on a radius graph built from the positions."""

    def __init__(self, cfg: dict):
        super().__init__()
        from physicsnemo.models.meshgraphnet import MeshGraphNet
        h, layers = cfg["hidden"], cfg["mlp_layers"]
        self.net = MeshGraphNet(
            input_dim_nodes=5, input_dim_edges=4, output_dim=3,
            processor_size=cfg["processor_size"], mlp_activation_fn="relu",
            num_layers_node_processor=layers, num_layers_edge_processor=layers,
            hidden_dim_processor=h, hidden_dim_node_encoder=h, num_layers_node_encoder=layers,
            hidden_dim_edge_encoder=h, num_layers_edge_encoder=layers,
            hidden_dim_node_decoder=h, num_layers_node_decoder=layers, aggregation="sum")
        self.radius, self.k = cfg["radius"], cfg["max_neighbors"]

    def graph(self, pos):
        return _radius_graph(pos, self.radius, self.k, loop=False)

    def forward(self, feats, pos):
        from torch_geometric.data import Data
        edges = self.graph(pos)
        dx = pos[edges[1]] - pos[edges[0]]  # x_receiver - x_sender
        efeat = torch.cat([dx, dx.norm(dim=-1, keepdim=True)], dim=-1)
        return self.net(feats, efeat, Data(edge_index=edges, num_nodes=pos.shape[0]))


class _Transolver(nn.Module):
    """PhysicsNeMo Transolver fed the MPNN embedding of the radius graph (self loops)."""

    def __init__(self, cfg: dict):
        super().__init__()
        from physicsnemo.models.transolver import Transolver
        self.embedding = MPNNEmbedding(5, cfg["hidden"], cfg["mp_steps"])
        self.net = Transolver(
            functional_dim=5, out_dim=3, embedding_dim=cfg["hidden"], n_layers=cfg["layers"],
            n_hidden=cfg["hidden"], dropout=cfg["dropout"], n_head=cfg["heads"], act="gelu",
            mlp_ratio=cfg["mlp_ratio"], slice_num=cfg["slices"], use_te=False)
        self.radius, self.k = cfg["radius"], cfg["max_neighbors"]

    def graph(self, pos):
        return _radius_graph(pos, self.radius, self.k, loop=True)

    def forward(self, feats, pos):
        emb = self.embedding(feats, pos, self.graph(pos))
        return self.net(feats[None], embedding=emb[None])[0]


class _Erwin(nn.Module):
    """The official ErwinTransformer (ball tree and radius graph built inside) and its head."""

    def __init__(self, cfg: dict, erwin_src: str):
        super().__init__()
        path = os.path.join(erwin_src, "models", "erwin.py")
        spec = importlib.util.spec_from_file_location("erwin_official", path)
        module = importlib.util.module_from_spec(spec)
        sys.modules[spec.name] = module  # its dataclasses look their module up
        spec.loader.exec_module(module)
        strides = list(cfg["strides"])
        widths = [cfg["hidden"] * (math.prod(strides[:i]) if cfg["widen"] else 1)
                  for i in range(len(cfg["enc_depths"]))]
        self.net = module.ErwinTransformer(
            c_in=5, c_hidden=widths, ball_sizes=list(cfg["ball_sizes"]),
            enc_num_heads=list(cfg["enc_heads"]), enc_depths=list(cfg["enc_depths"]),
            dec_num_heads=list(cfg["dec_heads"]), dec_depths=list(cfg["dec_depths"]),
            strides=strides, rotate=int(cfg["rotate"]), mlp_ratio=cfg["mlp_ratio"],
            dimensionality=3, mp_steps=cfg["mp_steps"])
        self.head = nn.Sequential(nn.Linear(widths[0], widths[0]), nn.GELU(),
                                  nn.Linear(widths[0], 3))
        self.radius = cfg["radius"]

    def graph(self, pos):  # what the official forward builds (torch_cluster's default cap, 32)
        import torch_cluster
        return torch_cluster.radius_graph(pos, self.radius, loop=True)

    def forward(self, feats, pos):
        batch = torch.zeros(pos.shape[0], dtype=torch.long)
        return self.head(self.net(feats, pos, batch, radius=self.radius))


def build_peer(name: str, cfg: dict, erwin_src: str) -> nn.Module:
    """The peer of thrombojax's ``name`` model for its config dict (``config_to_dict``)."""
    if name == "erwin":
        return _Erwin(cfg, erwin_src)
    return {"mgn": _MGN, "transolver": _Transolver}[name](cfg)


def _setup(model, inp, lr):
    """Tensors of one sample and the step / loss functions of the peer ``model``."""
    t = {k: torch.from_numpy(getattr(inp, k)) for k in ("x_prev", "x_cur", "x_next")}
    clot = torch.from_numpy(inp.node_type == 1)
    one_hot = nn.functional.one_hot(torch.from_numpy(inp.node_type).long(), 2).float()
    mean, std, vstd = STATS["mean"], STATS["std"], STATS["velocity_std"]

    def features(x_prev, x_cur):
        return torch.cat([(x_cur - x_prev) / vstd, one_hot], dim=-1)

    def step(x_prev, x_cur):
        accel = model(features(x_prev, x_cur), x_cur) * std + mean
        return torch.where(clot[:, None], x_cur + (x_cur - x_prev) + accel, x_cur)

    target = ((t["x_next"] - 2 * t["x_cur"] + t["x_prev"]) - mean) / std
    opt = torch.optim.AdamW(model.parameters(), lr=lr, weight_decay=0.01)

    def train():
        opt.zero_grad(set_to_none=True)
        out = model(features(t["x_prev"], t["x_cur"]), t["x_cur"])
        loss = ((out - target) ** 2).mean(dim=-1)[clot].mean()
        loss.backward()
        opt.step()
        return loss

    return t, features, step, train


def _case(name, kind, model, inp, spec) -> Case:
    t, features, step, train = _setup(model, inp, spec["lr"][name])
    n, key = inp.n_nodes, f"{name}|{kind}|{inp.n_nodes}"
    with torch.inference_mode():
        info = {"edges_per_node": round(model.graph(t["x_cur"]).shape[1] / n, 2)}
    if kind == "train":
        model.train()
        return Case(key, train, repeats=spec["repeats"], info=info)
    model.eval()

    def run_step():
        with torch.inference_mode():
            return step(t["x_prev"], t["x_cur"])

    def run_rollout():
        with torch.inference_mode():
            prev, cur, traj = t["x_prev"], t["x_cur"], []
            for _ in range(spec["rollout_steps"]):
                prev, cur = cur, step(prev, cur)
                traj.append(cur)
            return torch.stack(traj)

    def run_forward():
        with torch.inference_mode():
            return model(features(t["x_prev"], t["x_cur"]), t["x_cur"])

    run = {"step": run_step, "rollout": run_rollout, "forward": run_forward}[kind]
    return Case(key, run, model_steps=spec["rollout_steps"] if kind == "rollout" else 1,
                repeats=spec["repeats"] if kind == "step" else 1, info=info)


def prepare(spec: dict) -> list[Case]:
    """Build every case of ``spec`` (one model per case; seeded) and run each once (warm-up)."""
    allow_cpu_torchvision()
    cases = []
    for name, kind, n in spec["cases"]:
        torch.manual_seed(0)
        model = build_peer(name, spec["configs"][name], spec["erwin_src"])
        case = _case(name, kind, model, read_inputs(spec["inputs"][str(n)]), spec)
        case.info["params"] = sum(p.numel() for p in model.parameters())
        case.run()  # warm-up
        cases.append(case)
    return cases


def versions() -> dict:
    """Versions of the PyTorch stack (installed distributions)."""
    out = {"torch_threads": torch.get_num_threads()}
    for dist in ("torch", "nvidia-physicsnemo", "torch_cluster", "torch_scatter",
                 "torch_geometric", "balltree-erwin"):
        try:
            out[dist] = importlib.metadata.version(dist)
        except importlib.metadata.PackageNotFoundError:
            out[dist] = None
    return out


if __name__ == "__main__":
    _spec = json.loads(sys.argv[1])
    torch.set_num_threads(_spec["threads"])
    _x = torch.randn(1 << 17)
    serve(prepare, _spec, versions(), probe=lambda: nn.functional.gelu(_x))
