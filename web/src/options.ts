// What the editor asks the engine for: a layer's solver settings at draft or final quality.

import type { SolveOptions } from './engine';
import { type Layer, type SceneDoc, layerSolver } from './scene';

export type Quality = 'draft' | 'final';

/** A draft (while dragging) solves on a grid about this many nodes across. */
export const DRAFT_TARGET_PX = 64;

/**
 * The solve request for a layer, as the scene engine would compute its field (so that
 * `inkwarp render` draws what the editor shows): the layer's method and its settings,
 * tension, tolerance, scheme and grid step, the drawing sampled every grid step. A draft uses a coarser grid
 * step (and sampling) and a looser tolerance, and lets `tps-exact` preview its field on
 * that coarser grid; the final solve uses the scene's own settings.
 */
export function solverOptions(doc: SceneDoc, layer: Layer, quality: Quality): SolveOptions {
  const s = layerSolver(doc, layer);
  const base = Math.max(1, s.grid_step ?? 1);
  const draft = Math.max(base, Math.ceil(Math.max(doc.width, doc.height) / DRAFT_TARGET_PX));
  const step = quality === 'draft' ? draft : base;
  return {
    method: s.method ?? 'tps',
    tension: s.tension ?? 0,
    tolerance: quality === 'draft' ? Math.max(s.tolerance ?? 0.01, 0.05) : (s.tolerance ?? 0.01),
    grid_step: step,
    max_cycles: s.max_cycles ?? null,
    scheme: s.scheme ?? 'multigrid',
    preview: quality === 'draft',
    spacing_px: step,
    border: layer.border === 'hold' ? 'hold' : 'free',
    ...(s.beier_neely ? { beier_neely: s.beier_neely } : {}),
    ...(s.tps_exact ? { tps_exact: s.tps_exact } : {}),
  };
}
