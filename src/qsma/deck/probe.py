"""The probe and the levels of a deck's run, which a deck does not give: the caller's,
else the node of largest displacement in the loaded tied mode and its deflections from
:data:`~qsma.deck.records.DEFAULT_LEVELS` of the model's size."""
from __future__ import annotations

import numpy as np

from ..analysis.config import parse_config
from ..errors import InputError
from ..fe import assemble_body
from ..mesh.celltypes import CELL_TYPES
from ..modal import linear_modes
from ..model.pairing import make_pairing
from .records import DEFAULT_LEVELS


class ProbeAndLevels:
    """The part of the deck reader (:class:`qsma.deck.reader._DeckReader`) that chooses
    the probe and the levels; it uses the reader's bodies, path and comments."""

    def _tip_and_levels(self, config, mode, tip_node, tip_direction, levels):
        """The probe (given, or the node of largest displacement in mode ``mode``) and the
        levels (given, or :data:`DEFAULT_LEVELS` of the model's size)."""
        tip, _ = self._given_tip(config, tip_node, tip_direction, levels)
        if tip_node is None or tip_direction is None:
            tip = self._mode_probe(config, mode, tip, tip_node is None,
                                   tip_direction is None)
        return tip, self._levels(levels)

    def _given_tip(self, config, tip_node, tip_direction, levels):
        """The probe as given (the first node of the first body where none is) and the
        levels."""
        dim = self._dim()
        if tip_node is not None:
            body, point = self._node_point(tip_node)
            self.comments[("tip",)] = f"node {tip_node} of the deck"
        else:
            first = self._body_list[0]
            body, point = first["table"]["name"], [float(v) for v in first["mesh"].points[0]]
        if tip_direction is None:
            direction = [1.0] + [0.0] * (dim - 1)
        else:
            direction = [float(v) for v in tip_direction]
            if len(direction) != dim:
                raise InputError(f"--tip-direction needs {dim} numbers (the model is "
                                 f"{dim}D), got {direction}")
        return {"points": [[body, point]], "direction": direction}, self._levels(levels)

    def _dim(self):
        return CELL_TYPES[self.asm.cell_types[0]].dim

    def _node_point(self, node_id):
        """``(body, coordinates)`` of the deck's node ``node_id``."""
        fm = self.asm.file_mesh
        idx = np.flatnonzero(np.asarray(fm.labels) == int(node_id))
        if not idx.size:
            raise InputError(f"--tip-node {node_id}: {self.path} has no node {node_id}")
        x = fm.points[idx[0]][:self._dim()]
        for b in self._body_list:
            if np.any(np.all(b["mesh"].points == x, axis=1)):
                return b["table"]["name"], [float(v) for v in x]
        raise InputError(f"--tip-node {node_id}: node {node_id} belongs to no body (no "
                         f"cell uses it)")

    def _mode_probe(self, config, mode, tip, pick_node, pick_direction):
        """The node (and axis) of largest displacement of mode ``mode`` of the tied
        structure."""
        cfg = dict(config, tip=tip, levels={"kind": "tip", "spacing": "list",
                                            "values": [1e-6]})
        model = parse_config(cfg, base=self.path.parent, where=self.path.name).model
        pairing = make_pairing(model)
        modes = linear_modes(model, [assemble_body(b) for b in model.bodies], pairing,
                             n_modes=mode + 1)
        shape = modes.shapes[:, mode]
        offsets = model.dof_offsets()
        best = None
        for k, b in enumerate(model.bodies):
            u = shape[offsets[k]:offsets[k + 1]].reshape(-1, model.dim)
            if pick_node:
                i = int(np.argmax(np.linalg.norm(u, axis=1)))
            else:
                i = int(b.mesh.node_sets["_tip"][0]) if b.name == tip["points"][0][0] \
                    else None
                if i is None:
                    continue
            size = float(np.linalg.norm(u[i]))
            if best is None or size > best[0]:
                best = (size, b, i, u[i])
        _, body, i, u = best
        point = [float(v) for v in body.mesh.points[i]]
        direction = tip["direction"]
        if pick_direction:
            axis = int(np.argmax(np.abs(u)))
            direction = [0.0] * model.dim
            direction[axis] = 1.0
        if pick_node:
            self.comments[("tip",)] = (f"the node of largest displacement in mode {mode} "
                                       f"of the tied structure (--tip-node ID for another)")
        return {"points": [[body.name, point]], "direction": direction}

    def _levels(self, levels):
        if levels is not None:
            if levels.kind == "tip" or levels.kind == "alpha":
                return {"kind": levels.kind, "spacing": "list",
                        "values": [float(v) for v in levels.values]}
        x = self.asm.file_mesh.points
        size = float(np.linalg.norm(x.max(axis=0) - x.min(axis=0)))
        lo, hi, n = DEFAULT_LEVELS
        self.comments[("levels",)] = (f"the probe's linear deflection from {lo:g} to {hi:g} "
                                      f"of the model's size {size:.6g} (--levels for others)")
        return {"kind": "tip", "spacing": "log", "start": lo * size, "stop": hi * size,
                "n": n}
