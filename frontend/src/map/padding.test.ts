import { describe, expect, it } from 'vitest';
import { outsideVisible, visiblePadding } from './padding';

const MAP = { left: 0, top: 0, right: 1000, bottom: 800 };

describe('visiblePadding', () => {
  it('adds nothing for a panel beside the map', () => {
    expect(visiblePadding({ left: 360, top: 0, right: 1280, bottom: 800 }, { left: 0, top: 0, right: 360, bottom: 800 }, 60)).toEqual({
      top: 60,
      bottom: 60,
      left: 60,
      right: 60,
    });
    expect(visiblePadding(MAP, null, 40).left).toBe(40);
  });
  it('keeps the box out from under a panel over the left of the map', () => {
    expect(visiblePadding(MAP, { left: 0, top: 0, right: 380, bottom: 800 }, 60)).toEqual({ top: 60, bottom: 60, left: 440, right: 60 });
  });
  it('keeps the box above a sheet over the bottom of the map', () => {
    expect(visiblePadding(MAP, { left: 0, top: 360, right: 1000, bottom: 800 }, 40)).toEqual({ top: 40, bottom: 480, left: 40, right: 40 });
  });
});

describe('outsideVisible', () => {
  const size = { width: 1000, height: 800 };
  const none = { top: 0, bottom: 0, left: 0, right: 0 };
  it('is false inside the visible part and true beyond its edges', () => {
    expect(outsideVisible(size, none, 500, 400)).toBe(false);
    expect(outsideVisible(size, none, -1, 400)).toBe(true);
    expect(outsideVisible(size, none, 500, 801)).toBe(true);
  });
  it('counts the part under a panel as not visible, and the margin before the edge', () => {
    const panel = { top: 0, bottom: 0, left: 380, right: 0 };
    expect(outsideVisible(size, panel, 300, 400)).toBe(true);
    expect(outsideVisible(size, panel, 400, 400)).toBe(false);
    expect(outsideVisible(size, panel, 400, 400, 40)).toBe(true);
    expect(outsideVisible(size, none, 970, 400, 40)).toBe(true);
  });
});
