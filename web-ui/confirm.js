// Confirmation for dangerous commands (force disarm, land all …): a modal <dialog> that
// resolves to true only when the operator presses the red button (Enter does, Escape and
// the other button do not). Test hooks: data-testid="confirm-dialog" / "confirm-ok" /
// "confirm-cancel".

let dialog = null;

function build() {
  const d = document.createElement('dialog');
  d.className = 'confirm';
  d.dataset.testid = 'confirm-dialog';
  d.innerHTML = `<form method="dialog">
      <h3 class="confirm-title"></h3>
      <p class="confirm-text"></p>
      <div class="confirm-buttons">
        <button value="cancel" class="btn" data-testid="confirm-cancel">Cancel</button>
        <button value="ok" class="btn danger" data-testid="confirm-ok" autofocus></button>
      </div>
    </form>`;
  document.body.append(d);
  return d;
}

/** Asks; resolves to true when confirmed. */
export function confirmAction(title, text, okLabel = 'Confirm') {
  if (!dialog) dialog = build();
  dialog.querySelector('.confirm-title').textContent = title;
  dialog.querySelector('.confirm-text').textContent = text;
  dialog.querySelector('[data-testid="confirm-ok"]').textContent = okLabel;
  dialog.returnValue = '';
  return new Promise((resolve) => {
    dialog.addEventListener('close', () => resolve(dialog.returnValue === 'ok'), { once: true });
    dialog.showModal();
  });
}
