// Non-blocking notifications in a corner; they fade out by themselves (errors stay longer)
// and close on click. At most a handful are kept on screen.

const MAX = 5;

export class Toasts {
  constructor(container) {
    this.el = container;
  }

  /** level: ok | info | warn | error. */
  show(level, title, text = '') {
    const t = document.createElement('div');
    t.className = `toast lvl-${level}`;
    t.dataset.level = level;
    const strong = document.createElement('strong');
    strong.textContent = title;
    t.append(strong);
    if (text) {
      const p = document.createElement('span');
      p.textContent = text;
      t.append(p);
    }
    t.title = 'click to dismiss';
    t.addEventListener('click', () => t.remove());
    this.el.append(t);
    while (this.el.childElementCount > MAX) this.el.firstElementChild.remove();
    const ms = level === 'error' ? 9000 : level === 'warn' ? 6000 : 3500;
    setTimeout(() => {
      t.classList.add('leaving');
      setTimeout(() => t.remove(), 300);
    }, ms);
  }
}
