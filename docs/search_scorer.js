/* Search ranking of the tanksynth docs (html_search_scorer in conf.py): the user's pages first.
 * The developers' module reference (_generated/api/) documents every internal module, whose
 * names contain the words a user searches ("observer", "kalman"): without this its ~200 module
 * pages fill the first screens of results and hide the method, plant and guide pages. */
var Scorer = {
  score: (result) => {
    const [docname, title, anchor, descr, score, filename, kind] = result;
    if (docname.startsWith("_generated/api/")) return score - 100;
    if (docname.startsWith("_generated/methods/") || docname.startsWith("_generated/plants/")) return score + 10;
    return score;
  },
  objNameMatch: 11,
  objPartialMatch: 6,
  objPrio: {0: 15, 1: 5, 2: -5},
  objPrioDefault: 0,
  title: 15,
  partialTitle: 7,
  term: 5,
  partialTerm: 2,
};
