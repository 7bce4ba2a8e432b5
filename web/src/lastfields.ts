// The solver worker's memory of each layer's last full-resolution field.

import type { FieldData, GridHandle, SolveFeature, SolveOptions, SolveReport } from './engine';

interface Last {
  field: FieldData;
  /** The request the field answers (features and options), when its solve converged. */
  answers: string | null;
  report: SolveReport;
}

/**
 * Each layer's last full-resolution field: the next warm solve's start, and the answer to
 * the same request again when the solve that made it converged. A drag's settle on the pose
 * the worker followed last (see `App.follow`) is drawn at once, not solved a second time.
 */
export class LastFields {
  private last = new Map<string, Last>();

  /**
   * The field of `features` under `options` on `grid`: solved (from the layer's last field
   * when `warm`), or that field itself when it answers this very request; `reused` says which.
   */
  solve(
    key: string,
    grid: Pick<GridHandle, 'solve'>,
    features: SolveFeature[],
    options: SolveOptions,
    warm: boolean,
  ): { field: FieldData; report: SolveReport; reused: boolean } {
    const request = JSON.stringify([features, options]);
    const kept = this.last.get(key);
    if (warm && kept && kept.answers === request) return { field: kept.field, report: kept.report, reused: true };
    const { field, report } = grid.solve(features, options, warm ? (kept?.field ?? null) : null);
    this.last.set(key, { field, report, answers: report.converged === false ? null : request });
    return { field, report, reused: false };
  }

  /**
   * The layer's grid was rebuilt: its last field no longer answers any request, and stays
   * as a start only when the grid kept its size.
   */
  regrid(key: string, width: number, height: number): void {
    const kept = this.last.get(key);
    if (!kept) return;
    if (kept.field.width !== width || kept.field.height !== height) this.last.delete(key);
    else kept.answers = null;
  }

  forget(key: string): void {
    this.last.delete(key);
  }

  clear(): void {
    this.last.clear();
  }
}
